:- module(macrop_generalize,
          [ generalize_plan/5,          % +Goals, +State, +Plan, +Options, -Macrop
            plan_domain/2               % +Options, -Domain
          ]).

/** <module> Plan generalization: a plan into a MACROP (the seed's Figure 4)

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
resources are collected from the steps.  The store and the lookup are prolog/macrop.pl's.

Options: domain(Spec) as for planner:plan/4.
*/

:- use_module(library(apply)).
:- use_module(library(error)).
:- use_module(library(lists)).
:- use_module(library(option)).
:- use_module(library(pairs)).
:- use_module(planner).


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

%!  plan_domain(+Options:list, -Domain) is det.
%
%   Domain is the compiled planning domain of Options' domain(Spec) (default the
%   operators of kb/operators.pl), or Spec itself when it is compiled already.

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
