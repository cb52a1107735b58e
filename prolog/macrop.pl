:- module(macrop,
          [ generalize_plan/5,          % +Goals, +State, +Plan, +Options, -Macrop
            macrop_applies/5,           % +Macrop, +Goals, +State, +Options, -Plan
            open_store/1,               % +File
            close_store/1,              % +File
            save_store/1,               % +File
            store_macrops/2,            % +File, -Macrops
            store_counts/4,             % +File, -Lookups, -Hits, -Misses
            add_macrop/3,               % +File, +Macrop, -Id
            lookup/5,                   % +File, +Goals, +State, +Options, -Plan
            operation_plan/5            % +File, +Goals, +State, +Options, -Result
          ]).

/** <module> Plan generalization and MACROP lookup

The two other parts of the seed's Operation Planner.

*Plan generalization* turns a plan into a MACROP (Figure 4):

    macrop(NameAndFormat,
           [ purpose(Goals),              % what the MACROP is for
             preconditions(Facts),        % must hold in the initial state
             adders(Facts),               % hold after the plan
             unary_constraints(Goals),
             n_ary_constraints(Goals),
             resources(Objects),
             plan(Steps)                  % step(N, Action, Predecessors)
           ])

Each step gets a fresh instance of its operator, so every constant the plan chose is a
variable; then each precondition a step takes from an earlier step is unified with that
step's adder (the links of a triangle table), which makes shared objects one variable.
Preconditions taken from the initial state are the overall preconditions; adders that
survive to the end of the plan are the overall adders; unary and n-ary constraints and
resources are collected from the steps.

*MACROP lookup* compares each MACROP to the goals (each goal must unify with a purpose)
and the initial state (each precondition must match a fact), checks the constraints and
returns the plan with the bindings plugged in.  Shorter plans are tried first.

*The store.*  MACROPs persist in a Prolog file, one `macrop(Id, NameAndFormat, Fields,
hits(N))` clause each and a `store_counts(Lookups, Hits, Misses)` clause, so a user can
read the file or consult it.  A store is opened by its file name, which the caller
chooses: learned MACROPs live apart from the hand-written ones of kb/macrops.pl, which
lookup/5 also consults.

Options: domain(Spec) and facts(Facts) as for planner:plan/4; constraints(Goals), goal
constraints that the bindings must satisfy.
*/

:- use_module(library(apply)).
:- use_module(library(error)).
:- use_module(library(lists)).
:- use_module(library(option)).
:- use_module(library(pairs)).
:- use_module(library(readutil)).
:- use_module(planner).
:- use_module('../kb/macrops', []).

:- dynamic stored/5.            % stored(File, Id, NameAndFormat, Fields, Hits)
:- dynamic counts/4.            % counts(File, Lookups, Hits, Misses)


                 /*******************************
                 *         GENERALIZATION       *
                 *******************************/

%!  generalize_plan(+Goals:list, +State:list, +Plan:list, +Options:list, -Macrop) is det.
%
%   Macrop is the generalization of Plan (steps as returned by planner:plan/4), which
%   achieves Goals from State.
%
%   @error domain_error(plan_for_goals, Plan) if Plan does not achieve Goals from State
%   @error domain_error(non_empty_plan, []) for an empty plan

generalize_plan(Goals, State, Plan, Options, Macrop) :-
    must_be(list(ground), Goals),
    must_be(list(ground), State),
    must_be(list, Plan),
    (   Plan == []
    ->  domain_error(non_empty_plan, Plan)
    ;   true
    ),
    plan_domain(Options, Domain),
    sort(State, State0),
    maplist(step_ops(Domain), Plan, Ground, General),
    simulate(Ground, General, 1, Domain, State0, [], Links, Final, Producers),
    maplist(link, Links),
    (   forall(member(G, Goals), memberchk(G, Final))
    ->  true
    ;   domain_error(plan_for_goals, Plan)
    ),
    overall_preconditions(Links, Pre),
    overall_adders(Producers, Final, General, Add),
    purpose(Goals, Producers, General, Purpose),
    collect(General, 5, Unary),
    collect(General, 6, Nary),
    collect(General, 7, Res),
    general_steps(Plan, General, Steps),
    Goals = [First|_],
    functor(First, Name, _),
    term_variables(Pre-Purpose-Steps, Vars),
    NameAndFormat =.. [Name|Vars],
    Macrop = macrop(NameAndFormat,
                    [ purpose(Purpose),
                      preconditions(Pre),
                      adders(Add),
                      unary_constraints(Unary),
                      n_ary_constraints(Nary),
                      resources(Res),
                      plan(Steps)
                    ]).

plan_domain(Options, Domain) :-
    option(domain(Spec), Options, module(operators)),
    (   Spec = planning_domain(_, _, _, _, _, _)
    ->  Domain = Spec
    ;   compile_domain(Spec, Domain)
    ).

%   step_ops(+Domain, +Step, -Ground, -General)
%
%   Ground is the operator instance of Step's action, General a fresh instance of the
%   same operator with every parameter a variable.

step_ops(Domain, step(_, Action, _), Ground, General) :-
    once(domain_operator(Domain, Action, Ground)),
    functor(Action, Name, Arity),
    functor(Skeleton, Name, Arity),
    once(domain_operator(Domain, Skeleton, General)).

%   simulate(+Ground, +General, +N, +Domain, +State0, +Producers0, -Links, -Final,
%            -Producers)
%
%   Run the ground steps from State0.  Producers maps each fact added so far to the
%   general adder that made it.  Links pairs every general precondition with the
%   general adder it was taken from, or with `initial`.

simulate([], [], _, _, State, Producers, [], State, Producers).
simulate([G|Gs], [V|Vs], N, Domain, State0, Producers0, Links, Final, Producers) :-
    G = op(Action, PreG, _, _, _, _, _),
    V = op(_, PreV, AddV, _, _, _, _),
    (   forall(member(P, PreG), memberchk(P, State0))
    ->  true
    ;   domain_error(executable_plan, Action)
    ),
    foldl(precondition_link(Producers0), PreG, PreV, Links, Links1),
    planner:apply_op_domain(Domain, G, State0, State1),
    G = op(_, _, AddG, _, _, _, _),
    foldl(produced(N), AddG, AddV, Producers0, Producers1),
    include(still_holds(State1), Producers1, Producers2),
    N1 is N + 1,
    simulate(Gs, Vs, N1, Domain, State1, Producers2, Links1, Final, Producers).

precondition_link(Producers, Fact, General, [General-From|Links], Links) :-
    (   memberchk(Fact-produced(_, Adder), Producers)
    ->  From = Adder
    ;   From = initial
    ).

produced(N, Fact, Adder, Producers0, [Fact-produced(N, Adder)|Producers1]) :-
    exclude(same_fact(Fact), Producers0, Producers1).

same_fact(Fact, Fact0-_) :-
    Fact0 == Fact.

still_holds(State, Fact-_) :-
    memberchk(Fact, State).

link(_-initial) :- !.
link(Pre-Adder) :-
    Pre = Adder.

%   The helpers below keep variable identity: no findall/3, which would copy.

overall_preconditions(Links, Pre) :-
    include(from_initial, Links, Initial),
    pairs_keys(Initial, Pre0),
    unique(Pre0, Pre).

from_initial(_-From) :-
    From == initial.

overall_adders(Producers, _Final, _General, Add) :-
    reverse(Producers, InOrder),
    pairs_values(InOrder, Produced),
    maplist(produced_adder, Produced, Add0),
    unique(Add0, Add).

produced_adder(produced(_, Adder), Adder).

purpose(Goals, Producers, _General, Purpose) :-
    foldl(goal_adder(Producers), Goals, Purpose0, []),
    unique(Purpose0, Purpose).

goal_adder(Producers, Goal, [Adder|Rest], Rest) :-
    memberchk(Goal-produced(_, Adder), Producers), !.
goal_adder(_, _, Rest, Rest).

collect(General, Arg, Items) :-
    foldl(op_items(Arg), General, Items0, []),
    unique(Items0, Items).

op_items(Arg, Op, Items, Rest) :-
    arg(Arg, Op, Is),
    append(Is, Rest, Items).

%   unique(+List, -Set): List without later duplicates (==), order kept.

unique([], []).
unique([X|Xs], [X|Ys]) :-
    exclude(==(X), Xs, Rest),
    unique(Rest, Ys).

general_steps([], [], []).
general_steps([step(N, _, Preds)|Ss], [op(Action, _, _, _, _, _, _)|Os],
              [step(N, Action, Preds)|Ts]) :-
    general_steps(Ss, Os, Ts).


                 /*******************************
                 *            LOOKUP            *
                 *******************************/

%!  macrop_applies(+Macrop, +Goals:list, +State:list, +Options:list, -Plan:list) is semidet.
%
%   Macrop achieves Goals from State: each goal unifies with a purpose of a fresh copy
%   of Macrop, each precondition matches a fact of State, the constraints hold, and Plan
%   is its plan with those bindings, ground.

macrop_applies(Macrop, Goals, State, Options, Plan) :-
    plan_domain(Options, Domain),
    option(facts(Facts), Options, []),
    option(constraints(GoalConstraints), Options, []),
    applies(Macrop, Domain, Facts, GoalConstraints, Goals, State, Plan).

applies(Macrop, Domain, Facts, GoalConstraints, Goals, State, Plan) :-
    copy_term(Macrop, macrop(_, Fields)),
    memberchk(purpose(Purpose), Fields),
    memberchk(preconditions(Pre), Fields),
    maplist(in_purpose(Purpose), Goals),
    match_all(Pre, State),
    memberchk(unary_constraints(Unary), Fields),
    memberchk(n_ary_constraints(Nary), Fields),
    append([Unary, Nary, GoalConstraints], Constraints),
    constraints_hold(Domain, Facts, Constraints),
    memberchk(plan(Plan), Fields),
    ground(Plan),
    !.

in_purpose(Purpose, Goal) :-
    member(Goal, Purpose).

match_all([], _).
match_all([P|Ps], State) :-
    member(P, State),
    match_all(Ps, State).


                 /*******************************
                 *             STORE            *
                 *******************************/

%!  open_store(+File) is det.
%
%   Load the MACROP store File (an empty store if the file does not exist yet),
%   replacing what was loaded from it before.
%
%   @error syntax_error(...) if File is not a readable Prolog file

open_store(File) :-
    must_be(atom, File),
    close_store(File),
    assertz(counts(File, 0, 0, 0)),
    (   exists_file(File)
    ->  read_file_to_terms(File, Terms, []),
        maplist(load_term(File), Terms)
    ;   true
    ).

load_term(File, macrop(Id, Name, Fields, hits(Hits))) :- !,
    assertz(stored(File, Id, Name, Fields, Hits)).
load_term(File, store_counts(Lookups, Hits, Misses)) :- !,
    retractall(counts(File, _, _, _)),
    assertz(counts(File, Lookups, Hits, Misses)).
load_term(File, Term) :-
    domain_error(macrop_store_term(File), Term).

%!  close_store(+File) is det.
%
%   Forget the store File (without saving it).

close_store(File) :-
    must_be(atom, File),
    retractall(stored(File, _, _, _, _)),
    retractall(counts(File, _, _, _)).

%!  save_store(+File) is det.
%
%   Write the open store File back to File (through a temporary file, so that a crash
%   never leaves half a store).
%
%   @error existence_error(macrop_store, File) if File is not open

save_store(File) :-
    must_be_open(File),
    counts(File, Lookups, Hits, Misses),
    findall(macrop(Id, Name, Fields, hits(H)), stored(File, Id, Name, Fields, H), Macrops),
    atom_concat(File, '.tmp', Tmp),
    setup_call_cleanup(open(Tmp, write, Out),
                       write_store(Out, Lookups, Hits, Misses, Macrops),
                       close(Out)),
    rename_file(Tmp, File).

write_store(Out, Lookups, Hits, Misses, Macrops) :-
    format(Out, '%   Learned MACROPs of the ITA Operation Planner (prolog/macrop.pl).~n', []),
    format(Out, '%   macrop(Id, NameAndFormat, Fields, hits(Hits)); read with open_store/1.~n~n', []),
    portray_clause(Out, store_counts(Lookups, Hits, Misses)),
    nl(Out),
    forall(member(M, Macrops), (portray_clause(Out, M), nl(Out))).

must_be_open(File) :-
    must_be(atom, File),
    (   counts(File, _, _, _)
    ->  true
    ;   existence_error(macrop_store, File)
    ).

%!  store_macrops(+File, -Macrops:list) is det.
%
%   Macrops are the `macrop(Id, NameAndFormat, Fields, hits(N))` of the open store File.

store_macrops(File, Macrops) :-
    must_be_open(File),
    findall(macrop(Id, Name, Fields, hits(H)), stored(File, Id, Name, Fields, H), Macrops).

%!  store_counts(+File, -Lookups:integer, -Hits:integer, -Misses:integer) is det.
%
%   The lookups made in store File and how many found a MACROP (hand-written ones
%   included) and how many did not.

store_counts(File, Lookups, Hits, Misses) :-
    must_be_open(File),
    counts(File, Lookups, Hits, Misses).

%!  add_macrop(+File, +Macrop, -Id:integer) is det.
%
%   Store Macrop in the open store File under the new number Id, unless a variant of it
%   is there already (then Id is that one's number).

add_macrop(File, macrop(Name, Fields), Id) :-
    must_be_open(File),
    (   stored(File, Id0, Name0, Fields0, _),
        macrop(Name0, Fields0) =@= macrop(Name, Fields)
    ->  Id = Id0
    ;   aggregate_all(max(I), stored(File, I, _, _, _), Max)
    ->  Id is Max + 1,
        assertz(stored(File, Id, Name, Fields, 0))
    ;   Id = 1,
        assertz(stored(File, Id, Name, Fields, 0))
    ).

%!  lookup(+File, +Goals:list, +State:list, +Options:list, -Found) is det.
%
%   Found is `found(Id, Plan)` for the first MACROP (fewest steps first; the learned
%   ones of store File, then the hand-written ones of kb/macrops.pl, whose Id is
%   `kb(Name)`) that achieves Goals from State, or `none`.  The store's counts and the
%   MACROP's hits are updated.

lookup(File, Goals, State, Options, Found) :-
    must_be_open(File),
    must_be(list, Goals),
    must_be(list, State),
    plan_domain(Options, Domain),
    option(facts(Facts), Options, []),
    option(constraints(GoalConstraints), Options, []),
    candidates(File, Candidates),
    (   member(Id-Macrop, Candidates),
        applies(Macrop, Domain, Facts, GoalConstraints, Goals, State, Plan)
    ->  Found = found(Id, Plan),
        count(File, hit(Id))
    ;   Found = none,
        count(File, miss)
    ).

candidates(File, Candidates) :-
    findall(Len-(Id-macrop(Name, Fields)),
            ( stored(File, Id, Name, Fields, _),
              plan_length(Fields, Len)
            ),
            Learned),
    findall(Len-(kb(Name)-macrop(Name, Fields)),
            ( macrops:macrop(Name, Fields),
              plan_length(Fields, Len)
            ),
            Written),
    append(Learned, Written, All),
    keysort(All, Sorted),
    pairs_values(Sorted, Candidates).

plan_length(Fields, Len) :-
    memberchk(plan(Steps), Fields),
    length(Steps, Len).

count(File, Event) :-
    retract(counts(File, L0, H0, M0)),
    L is L0 + 1,
    (   Event = hit(Id)
    ->  H is H0 + 1, M = M0,
        hit(File, Id)
    ;   H = H0, M is M0 + 1
    ),
    assertz(counts(File, L, H, M)).

hit(File, Id) :-
    (   retract(stored(File, Id, Name, Fields, N0))
    ->  N is N0 + 1,
        assertz(stored(File, Id, Name, Fields, N))
    ;   true                               % a hand-written MACROP
    ).

%!  operation_plan(+File, +Goals:list, +State:list, +Options:list, -Result) is det.
%
%   The Operation Planner: MACROP lookup in store File first; when no MACROP applies,
%   the Task Planner plans from scratch and the plan is generalized and stored.  Result
%   is `macrop(Id, Plan)`, `planned(Id, Plan)` (Id of the new MACROP; `none` for an
%   empty plan) or `no_plan(Reason)` (see planner:plan_result/4).  Options are passed
%   to the planner too.

operation_plan(File, Goals, State, Options, Result) :-
    lookup(File, Goals, State, Options, Found),
    (   Found = found(Id, Plan)
    ->  Result = macrop(Id, Plan)
    ;   plan_result(Goals, State, Options, Planned),
        (   Planned = plan([])
        ->  Result = planned(none, [])
        ;   Planned = plan(Plan)
        ->  generalize_plan(Goals, State, Plan, Options, Macrop),
            add_macrop(File, Macrop, Id),
            Result = planned(Id, Plan)
        ;   Result = Planned
        )
    ).
