:- use_module(hddl).
:- use_module(htn).

/*  Tests of the HDDL reader: the language it supports, solved through the planner, and
    the errors (file and line) for what it does not.  */

domain_text("(define (domain kitchen)
  (:requirements :typing :negative-preconditions :equality :method-preconditions
                 :universal-preconditions :hierarchy)
  (:types cup glass - vessel vessel - object robot)
  (:constants tap - object)
  (:predicates (clean ?v - vessel) (full ?v - vessel) (at ?r - robot ?v - vessel))
  (:task serve :parameters (?v - vessel))
  (:task serve_all :parameters ())
  (:method serve_clean
    :parameters (?v - vessel ?r - robot)
    :task (serve ?v)
    :precondition (and (clean ?v) (not (full ?v)))
    :subtasks (and (t2 (fill ?r ?v)) (t1 (goto ?r ?v)))
    :ordering (and (< t1 t2)))
  (:method serve_dirty
    :parameters (?v - vessel ?r - robot)
    :task (serve ?v)
    :precondition (not (clean ?v))
    :ordered-subtasks (and (goto ?r ?v) (wash ?r ?v) (fill ?r ?v)))
  (:method all_done
    :parameters ()
    :task (serve_all)
    :precondition (forall (?v - (either cup glass)) (full ?v))
    :ordered-subtasks (and))
  (:method serve_next
    :parameters (?v - vessel)
    :task (serve_all)
    :precondition (not (full ?v))
    :ordered-subtasks (and (serve ?v) (serve_all)))
  (:action goto :parameters (?r - robot ?v - vessel)
    :effect (at ?r ?v))
  (:action wash :parameters (?r - robot ?v - vessel)
    :precondition (at ?r ?v)
    :effect (clean ?v))
  (:action fill :parameters (?r - robot ?v - vessel)
    :precondition (and (at ?r ?v) (clean ?v) (not (= ?v tap)))
    :effect (and (full ?v) (not (clean ?v)))))").

problem_text("(define (problem two) (:domain kitchen)
  (:objects c1 - cup g1 - glass rob - robot)
  (:htn :parameters () :ordered-subtasks (and (task0 (serve_all))))
  (:init (clean c1))
  (:goal (and (full c1) (full g1))))").

%   with_files(+DomainText, +ProblemText, :Goal): Goal(DomainFile, ProblemFile).
with_files(D, P, Goal) :-
    tmp_file(dom, DF0), atom_concat(DF0, '.hddl', DF),
    tmp_file(prob, PF0), atom_concat(PF0, '.hddl', PF),
    setup_call_cleanup(( write_text(DF, D), write_text(PF, P) ),
                       call(Goal, DF, PF),
                       ( delete_file(DF), delete_file(PF) )).

write_text(File, Text) :-
    setup_call_cleanup(open(File, write, Out), write(Out, Text), close(Out)).

state_of(State, DF, PF) :-
    read_hddl(DF, PF, hddl_task(_, State, _, _)).

solved(Actions, DF, PF) :-
    hddl_solve(DF, PF, [time_limit(10)], plan(Steps, _, _)),
    pairs_values(Steps, Actions).

%   error_line(+Edit, -Line, -Message): the line and message of the error that the
%   domain text with Edit (Old-New, replacing the first Old) gives.
error_line(Old-New, Line, Message) :-
    domain_text(D0), problem_text(P),
    replace(D0, Old, New, D),
    catch(( with_files(D, P, [DF, PF]>>read_hddl(DF, PF, _)), Line = none, Message = "" ),
          error(hddl(_, Line, Message), _),
          true).

problem_error_line(Old-New, Line, Message) :-
    domain_text(D), problem_text(P0),
    replace(P0, Old, New, P),
    catch(( with_files(D, P, [DF, PF]>>read_hddl(DF, PF, _)), Line = none, Message = "" ),
          error(hddl(_, Line, Message), _),
          true).

replace(Text, Old, New, Result) :-
    sub_string(Text, Before, _, After, Old), !,
    sub_string(Text, 0, Before, _, Prefix),
    sub_string(Text, _, After, 0, Suffix),
    string_concat(Prefix, New, S1),
    string_concat(S1, Suffix, Result).

mentions(Message, Part) :-
    sub_string(Message, _, _, _, Part).

:- begin_tests(hddl_read).

test(sexprs_with_lines, Es == [l(1, [a, l(2, [b, var(x)])]), c]) :-
    string_codes("(A\n (b ?X)) ; comment\nc", Codes),
    parse_hddl(f, Codes, Es).

test(solves_with_types_ordering_forall_and_goal,
     Actions == [goto(rob, c1), fill(rob, c1), goto(rob, g1), wash(rob, g1), fill(rob, g1)]) :-
    domain_text(D), problem_text(P),
    with_files(D, P, solved(Actions)).

test(problem_parameters_are_typed,
     Actions == [goto(rob, c1), fill(rob, c1)]) :-
    domain_text(D), problem_text(P0),
    replace(P0, ":parameters () :ordered-subtasks (and (task0 (serve_all)))",
            ":parameters (?v - cup) :ordered-subtasks (and (task0 (serve ?v)))", P1),
    replace(P1, "(:goal (and (full c1) (full g1)))", "", P),
    with_files(D, P, solved(Actions)).

test(type_facts_include_ancestors_and_object, Types == [cup, object, vessel]) :-
    domain_text(D), problem_text(P),
    with_files(D, P, state_of(State)),
    findall(T, member('$type'(T, c1), State), Types0),
    sort(Types0, Types).

:- end_tests(hddl_read).

:- begin_tests(hddl_errors).

test(unbalanced_parenthesis, true(integer(Line))) :-
    error_line("(:requirements"-"((:requirements", Line, Message),
    assertion(mentions(Message, "unbalanced parentheses")).

test(partial_order_names_the_feature, true(Line == 9)) :-
    error_line(":ordering (and (< t1 t2))"-":ordering (and)", Line, Message),
    assertion(mentions(Message, "partial order is not supported")).

test(conditional_effect, true(Line == 37)) :-
    error_line("(full ?v) (not (clean ?v))"-"(when (clean ?v) (full ?v))", Line, Message),
    assertion(mentions(Message, "conditional effects (when) are not supported")).

test(quantified_effect, true(Line == 37)) :-
    error_line("(full ?v) (not (clean ?v))"-"(forall (?w - cup) (full ?w))", Line, Message),
    assertion(mentions(Message, "(forall) are not supported")).

test(undeclared_predicate, true(Line == 36)) :-
    error_line("(at ?r ?v) (clean ?v)"-"(near ?r ?v) (clean ?v)", Line, Message),
    assertion(mentions(Message, "near is not declared")).

test(wrong_arity, true(Line == 33)) :-
    error_line("(at ?r ?v)\n    :effect (clean"-"(at ?r)\n    :effect (clean", Line, Message),
    assertion(mentions(Message, "1 arguments here but 2")).

test(unsupported_requirement, true(Line == 2)) :-
    error_line(":typing"-":numeric-fluents", Line, Message),
    assertion(mentions(Message, ":numeric-fluents is not supported")).

test(unknown_variable, true(Line == 12)) :-
    error_line("(not (full ?v))"-"(not (full ?w))", Line, Message),
    assertion(mentions(Message, "?w is not a parameter")).

test(unknown_subtask, true(Line == 13)) :-
    error_line("(t2 (fill ?r ?v))"-"(t2 (pour ?r ?v))", Line, Message),
    assertion(mentions(Message, "pour/2 is neither a task nor an action")).

test(functions_section, true(Line == 7)) :-
    error_line("  (:task serve "-"  (:functions (level ?v - vessel))\n  (:task serve ", Line, Message),
    assertion(mentions(Message, "numeric fluents")).

test(undeclared_object_in_init, true(Line == 4)) :-
    problem_error_line("(clean c1)"-"(clean c9)", Line, Message),
    assertion(mentions(Message, "object c9 is not declared")).

test(domain_name_of_the_problem_is_not_checked, true(Line == none)) :-
    problem_error_line("(:domain kitchen)"-"(:domain garage)", Line, _).

:- end_tests(hddl_errors).
