:- use_module(pddl).
:- use_module(planner).

/*  Tests of the STRIPS PDDL reader and of solving through the Task Planner.  */

typed_domain("
; a typed toy: carry parcels between rooms
(define (domain Carry)
  (:requirements :strips :typing)
  (:types parcel robot - thing room)
  (:predicates (at ?t - thing ?r - room) (in ?p - parcel ?b - robot)
               (door ?a ?b - room))
  (:action Move :parameters (?b - robot ?from ?to - room)
     :precondition (and (at ?b ?from) (door ?from ?to))
     :effect (and (at ?b ?to) (not (at ?b ?from))))
  (:action Load :parameters (?p - parcel ?b - robot ?r - room)
     :precondition (and (at ?p ?r) (at ?b ?r))
     :effect (and (in ?p ?b) (not (at ?p ?r))))
  (:action Unload :parameters (?p - parcel ?b - robot ?r - room)
     :precondition (and (in ?p ?b) (at ?b ?r))
     :effect (and (at ?p ?r) (not (in ?p ?b)))))").

typed_problem("
(define (problem carry-1) (:domain carry)
  (:objects p1 p2 - parcel r2d2 - robot kitchen hall lab - room)
  (:init (at p1 kitchen) (at p2 hall) (at r2d2 hall)
         (door kitchen hall) (door hall kitchen) (door hall lab) (door lab hall))
  (:goal (and (at p1 lab) (at p2 lab))))").

with_files(Goal) :-
    typed_domain(D), typed_problem(P),
    tmp_file(dom, DF0), atom_concat(DF0, '.pddl', DF),
    tmp_file(prob, PF0), atom_concat(PF0, '.pddl', PF),
    setup_call_cleanup(( write_text(DF, D), write_text(PF, P) ),
                       call(Goal, DF, PF),
                       ( delete_file(DF), delete_file(PF) )).

write_text(File, Text) :-
    setup_call_cleanup(open(File, write, Out), write(Out, Text), close(Out)).

%   simulate(+Actions, +Domain, +State0, -State): run a plan with apply_action/4.
simulate([], _, State, State).
simulate([A|As], Domain, State0, State) :-
    apply_action(Domain, A, State0, State1),
    simulate(As, Domain, State1, State).

domain_names(Names, Types, DF, _PF) :-
    read_pddl_domain(DF, pddl_domain(carry, _, Types, _, Actions)),
    findall(N, member(action(N, _, _, _, _), Actions), Names).

move_operator(Op, DF, PF) :-
    pddl_task(DF, PF, task(D, _, _)),
    once(domain_operator(D, move(_, _, _), Op)).

task_facts(State, Goals, DF, PF) :-
    pddl_task(DF, PF, task(_, State, Goals)).

solved_validly(Valid, DF, PF) :-
    pddl_task(DF, PF, task(D, S0, Goals)),
    solve_pddl(DF, PF, [time_limit(10)], plan(Actions)),
    simulate(Actions, D, S0, S),
    (   forall(member(G, Goals), memberchk(G, S))
    ->  Valid = true
    ;   Valid = false
    ).

solve_with_tiny_effort(Result, DF, PF) :-
    solve_pddl(DF, PF, [max_effort(1)], Result).

:- begin_tests(pddl_reader).

test(sexprs, true(E == [[define, [domain, d], [':requirements', ':strips']], 42])) :-
    string_codes("(define (DOMAIN d) ; comment\n (:requirements :STRIPS)) 42", Codes),
    parse_sexprs(Codes, E).

test(variables, true(E == [[at, var(x), room1]])) :-
    string_codes("(at ?X room1)", Codes),
    parse_sexprs(Codes, E).

test(unbalanced, error(syntax_error(pddl(missing_close_parenthesis)))) :-
    string_codes("(define (domain d)", Codes),
    parse_sexprs(Codes, _).

test(typed_domain, true(Names-Types == [move, load, unload]-[parcel-thing, robot-thing, room-object])) :-
    with_files(domain_names(Names, Types)).

test(static_precondition_becomes_constraint,
     true(Op =@= op(move(B, F, T), [at(B, F)], [at(B, T)], [at(B, F)],
                    [type(B, robot), type(F, room), type(T, room)], [door(F, T)], []))) :-
    with_files(move_operator(Op)).

test(problem, true(Goals-State == [at(p1, lab), at(p2, lab)]-
                                 [at(p1, kitchen), at(p2, hall), at(r2d2, hall)])) :-
    with_files(task_facts(State, Goals)).

test(unsupported_requirement, error(domain_error(pddl_requirement, ':adl'))) :-
    tmp_file(adl, F),
    write_text(F, "(define (domain x) (:requirements :adl))"),
    call_cleanup(read_pddl_domain(F, _), delete_file(F)).

:- end_tests(pddl_reader).

:- begin_tests(pddl_solving).

test(typed_problem_solved_and_plan_valid, true(Valid == true)) :-
    with_files(solved_validly(Valid)).

test(ipc_format, true(Text == "(load p1 r2d2 kitchen)\n(move r2d2 kitchen hall)\n")) :-
    with_output_to(string(Text),
                   print_ipc_plan([load(p1, r2d2, kitchen), move(r2d2, kitchen, hall)])).

test(no_plan_reason, true(R = no_plan(_))) :-
    with_files(solve_with_tiny_effort(R)).

:- end_tests(pddl_solving).
