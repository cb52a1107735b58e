:- module(planner,
          [ plan/4,                     % +Goals, +State, +Options, -Plan
            plan_result/4,              % +Goals, +State, +Options, -Result
            plan_linear/4,              % +Goals, +State, +Options, -Actions
            plan_text/4,                % +Goals, +State, +Options, -Rows
            compile_domain/2,           % +Spec, -Domain
            domain_operator/3,          % +Domain, ?Action, -Operator
            apply_action/4,             % +Domain, +Action, +State0, -State
            partial_order/3,            % +Domain, +Actions, -Plan
            constraints_hold/3,         % +Domain, +Facts, +Constraints
            relaxed_costs/3             % +Relaxed, +State, -Costs
          ]).

/** <module> The Task Planner of the Operation Planner

A hierarchical, nonlinear, backward-chaining planner in the manner of the seed's Task
Planner:

  - *Backward chaining.*  A goal that does not hold is achieved by an operator whose
    adders contain it; the operator's preconditions become subgoals, worked on from the
    current state (means-ends analysis); the operator is then applied.
  - *Hierarchical* in the ABSTRIPS sense.  Goals and preconditions carry criticality
    weights; of the unsatisfied ones, only those of the highest weight are worked on, and
    when a step clobbers a goal of a higher level that level is worked on again first.
  - *Nonlinear.*  The plan is a set of numbered steps, each with the list of steps that
    must precede it (Figure 4).  Two steps are ordered only when they interact (one
    produces, deletes or needs what the other needs, produces or deletes) or share a
    resource; steps with no interaction stay unordered.
  - *Serendipitous goal reduction.*  Every goal is checked against the current state
    before it is worked on, so a goal achieved on the way is dropped.
  - *Deductive operators* instead of delete lists: a fact added by a step denies the
    propositions its deductive operators name.  Operators read from PDDL may carry an
    explicit `deleters/1` field too.
  - *Constraints.*  Unary constraints generate candidate bindings for an operator's
    variables, n-ary constraints test them; constraints are answered by the domain's
    static facts, never by the state.
  - *Hill climbing with chronological backtracking.*  The candidate establishers of a
    goal are ordered by an estimate (unsatisfied preconditions, or the additive relaxed
    cost of the preconditions when the domain carries a grounded relaxation, plus a
    penalty for clobbering protected goals); the best is tried first, the others on
    backtracking.
  - *A bound on effort.*  Every establisher tried counts; past the bound the search stops
    with the reason `effort_exhausted(Tried, Bound)`.

The state and goals are arguments: lists of facts.  A domain is compiled by
compile_domain/2 from a module holding static_operator/2 and deductive_operator/2
(default `operators`, kb/operators.pl) or from a list of operator terms (PDDL).

Options of plan/4 and plan_result/4:

  - domain(+Domain): a compiled domain or a spec for compile_domain/2
    (default `module(operators)`)
  - constraints(+Goals): constraints the bindings of the goals' variables must satisfy
    (e.g. `type(Tool, us_tool)`)
  - facts(+Facts): extra static facts for the constraints
  - max_effort(+N): establishers tried before giving up (default 20000)
  - max_depth(+N): depth of the goal stack (default 40)
  - rounds(+N): times each goal list may be reworked after a clobber (default 4)
*/

:- use_module(library(apply)).
:- use_module(library(assoc)).
:- use_module(library(error)).
:- use_module(library(lists)).
:- use_module(library(option)).
:- use_module(library(pairs)).
:- use_module(library(ordsets)).
:- use_module(library(aggregate)).
:- use_module(library(debug)).
:- use_module('../kb/operators', []).


                 /*******************************
                 *          ENTRY POINTS        *
                 *******************************/

%!  plan(+Goals:list, +State:list, +Options:list, -Plan:list) is semidet.
%
%   Plan is a nonlinear plan that achieves Goals from State: a list of
%   `step(N, Action, Predecessors)` in execution order, N from 1, Predecessors the
%   numbers of the steps that must be done before step N.  Fails when no plan is found;
%   plan_result/4 says why.  Variables of Goals are bound to the values the plan uses.
%
%   @error type_error(list, X) if Goals, State or Options is not a list
%   @error instantiation_error if State holds a fact that is not ground

plan(Goals, State, Options, Plan) :-
    plan_result(Goals, State, Options, Result),
    Result = plan(Plan).

%!  plan_result(+Goals:list, +State:list, +Options:list, -Result) is det.
%
%   Result is `plan(Plan)` as for plan/4, or `no_plan(Reason)` where Reason is one of
%
%     - no_operator(Goal): nothing in the domain adds Goal and the state lacks it
%     - effort_exhausted(Tried, Bound): the effort bound was hit
%     - search_exhausted(Tried): every alternative within the bounds failed

plan_result(Goals, State, Options, Result) :-
    must_be(list, Goals),
    must_be(list, State),
    must_be(list, Options),
    maplist(must_be(ground), State),
    maplist(must_be(callable), Goals),
    context(Goals, Options, Ctx),
    sort(State, State0),
    (   unachievable_goal(Goals, Ctx, State0, Goal)
    ->  Result = no_plan(no_operator(Goal))
    ;   search_result(Goals, Ctx, State0, Result)
    ).

%!  plan_linear(+Goals:list, +State:list, +Options:list, -Actions:list) is semidet.
%
%   Actions are the steps of the plan in execution order (one linearization).

plan_linear(Goals, State, Options, Actions) :-
    plan(Goals, State, Options, Plan),
    findall(Action, member(step(_, Action, _), Plan), Actions).

%!  plan_text(+Goals:list, +State:list, +Options:list, -Rows:list) is det.
%
%   JSON-friendly variant of plan_result/4 for callers that want atoms: Rows is
%   `[ok, Steps]` with each step `[N, ActionText, Predecessors]`, or
%   `[no_plan, ReasonText]`.

plan_text(Goals, State, Options, Rows) :-
    plan_result(Goals, State, Options, Result),
    (   Result = plan(Plan)
    ->  maplist(step_row, Plan, Steps),
        Rows = [ok, Steps]
    ;   Result = no_plan(Reason),
        format(atom(Text), '~q', [Reason]),
        Rows = [no_plan, Text]
    ).

step_row(step(N, Action, Preds), [N, Text, Preds]) :-
    format(atom(Text), '~q', [Action]).

search_result(Goals, Ctx, State0, Result) :-
    ctx_effort(Ctx, Effort),
    catch(( top_search(Goals, Ctx, State0, Actions)
          ->  ctx_domain(Ctx, Domain),
              partial_order_ops(Domain, Actions, Plan),
              Result = plan(Plan)
          ;   arg(1, Effort, Tried),
              Result = no_plan(search_exhausted(Tried))
          ),
          planner_effort(Tried, Bound),
          Result = no_plan(effort_exhausted(Tried, Bound))).

%   top_search(+Goals, +Ctx, +State0, -Actions)
%
%   Achieve Goals.  When achieving a top-level goal G2 clobbers a top-level goal G1
%   achieved before, the search starts again with G2 ranked above G1: the criticalities
%   of the top-level goals are learned from their interactions (until an ordering would
%   be cyclic; then the clobbered goal is simply achieved again).

top_search(Goals, Ctx, State0, Actions) :-
    ctx_rounds(Ctx, Rounds0),
    length(Goals, N),
    Rounds is Rounds0*N + 2,
    catch(( achieve_all(Goals, [], Ctx, Rounds, State0, _State, [], Done),
            goal_constraints_hold(Ctx)
          ),
          planner_restart(Before-After),
          true),
    (   var(Before)
    ->  reverse(Done, Actions)
    ;   ctx_precedences(Ctx, Precedences),
        nb_setarg(9, Ctx, [Before-After|Precedences]),
        top_search(Goals, Ctx, State0, Actions)
    ).

%!  unachievable_goal(+Goals, +Ctx, +State, -Goal) is semidet.
%
%   Goal of Goals holds in no way: it is not in State and no operator adds it.

unachievable_goal(Goals, Ctx, State, Goal) :-
    ctx_domain(Ctx, Domain),
    member(Goal, Goals),
    \+ memberchk(Goal, State),
    \+ ( domain_achiever(Domain, Goal, _) ),
    !.


                 /*******************************
                 *            CONTEXT           *
                 *******************************/

% ctx(Domain, Effort, MaxDepth, Rounds, Cache, GoalConstraints, TopGoals, Facts,
%     Precedences)
context(Goals, Options, ctx(Domain, effort(0, MaxEffort), MaxDepth, Rounds,
                            cache(none, none), Constraints, Goals, Facts, [])) :-
    option(domain(Spec), Options, module(operators)),
    (   Spec = planning_domain(_, _, _, _, _, _)
    ->  Domain = Spec
    ;   compile_domain(Spec, Domain)
    ),
    option(max_effort(MaxEffort), Options, 20000),
    option(max_depth(MaxDepth), Options, 40),
    option(rounds(Rounds), Options, 4),
    option(constraints(Constraints), Options, []),
    option(facts(Facts), Options, []),
    must_be(positive_integer, MaxEffort),
    must_be(positive_integer, MaxDepth),
    must_be(nonneg, Rounds),
    must_be(list, Constraints),
    must_be(list(ground), Facts).

ctx_domain(Ctx, Domain) :- arg(1, Ctx, Domain).
ctx_effort(Ctx, Effort) :- arg(2, Ctx, Effort).
ctx_depth(Ctx, Depth) :- arg(3, Ctx, Depth).
ctx_rounds(Ctx, Rounds) :- arg(4, Ctx, Rounds).
ctx_cache(Ctx, Cache) :- arg(5, Ctx, Cache).
ctx_constraints(Ctx, Constraints) :- arg(6, Ctx, Constraints).
ctx_top_goals(Ctx, Goals) :- arg(7, Ctx, Goals).
ctx_facts(Ctx, Facts) :- arg(8, Ctx, Facts).
ctx_precedences(Ctx, Precedences) :- arg(9, Ctx, Precedences).

tick(Ctx) :-
    ctx_effort(Ctx, Effort),
    Effort = effort(Tried0, Bound),
    Tried is Tried0 + 1,
    nb_setarg(1, Effort, Tried),
    (   Tried > Bound
    ->  throw(planner_effort(Tried0, Bound))
    ;   true
    ).


                 /*******************************
                 *        GOAL ACHIEVEMENT      *
                 *******************************/

%   achieve_all(+Goals, +Stack, +Ctx, +Rounds, +State0, -State, +Done0, -Done)
%
%   Make all Goals hold together.  Goals are worked on in order of criticality (highest
%   first); the first that does not hold, given the bindings of those before it, is
%   achieved, and the list is checked again, at most Rounds times.

achieve_all(Goals, Stack, Ctx, Rounds, State0, State, Done0, Done) :-
    by_criticality(Goals, Stack, Ctx, Ordered),
    achieve_ordered(Ordered, Goals, Stack, Ctx, Rounds, State0, State, Done0, Done).

achieve_ordered(Ordered, Goals, Stack, Ctx, Rounds, State0, State, Done0, Done) :-
    first_unmatched(Ordered, State0, Unmatched),
    (   Unmatched == none
    ->  State = State0,
        Done = Done0
    ;   Rounds > 0,
        (   Stack == []
        ->  debug(planner(top), 'top-level goal ~p (rounds left ~d)', [Unmatched, Rounds])
        ;   true
        ),
        achieve(Unmatched, Goals, Stack, Ctx, State0, State1, Done0, Done1),
        clobber_check(Stack, Ctx, Unmatched, State0, State1),
        Rounds1 is Rounds - 1,
        achieve_ordered(Ordered, Goals, Stack, Ctx, Rounds1, State1, State, Done1, Done)
    ).

%   clobber_check(+Stack, +Ctx, +Achieved, +State0, +State1)
%
%   At the top level, if achieving Achieved denied a top-level goal that held, ask for a
%   restart with Achieved ranked first, unless that ordering would be cyclic.

clobber_check([_|_], _, _, _, _) :- !.
clobber_check([], Ctx, Achieved, State0, State1) :-
    ctx_top_goals(Ctx, Top),
    ctx_precedences(Ctx, Precedences),
    (   ground(Achieved),
        member(Goal, Top),
        ground(Goal),
        Goal \== Achieved,
        memberchk(Goal, State0),
        \+ memberchk(Goal, State1),
        \+ precedes(Precedences, Goal, Achieved),
        \+ precedes(Precedences, Achieved, Goal)
    ->  debug(planner(top), 'restart: ~p before ~p', [Achieved, Goal]),
        throw(planner_restart(Achieved-Goal))
    ;   true
    ).

precedes(Precedences, A, B) :-
    precedes(Precedences, A, B, []).

precedes(Precedences, A, B, _) :-
    memberchk(A-B, Precedences), !.
precedes(Precedences, A, B, Seen) :-
    member(A-C, Precedences),
    \+ memberchk(C, Seen),
    precedes(Precedences, C, B, [C|Seen]), !.

%   first_unmatched(+Goals, +State, -Unmatched) is nondet.
%
%   Match Goals against State in order, binding variables; Unmatched is the first goal
%   that matches no fact, or `none`.

first_unmatched([], _, none).
first_unmatched([Goal|Goals], State, Unmatched) :-
    (   ground(Goal)
    ->  (   memberchk(Goal, State)
        ->  first_unmatched(Goals, State, Unmatched)
        ;   Unmatched = Goal
        )
    ;   (   \+ memberchk(Goal, State)
        ->  Unmatched = Goal
        ;   member(Goal, State),
            first_unmatched(Goals, State, Unmatched)
        )
    ).

%   by_criticality(+Goals, +Stack, +Ctx, -Ordered)
%
%   Goals ordered by criticality, highest first, keeping the given order among equals.
%   Top-level goals are ranked by the domain's weights, then by the orderings learned
%   from clobbering (a goal that must come before others first).

by_criticality(Goals, Stack, Ctx, Ordered) :-
    ctx_domain(Ctx, Domain),
    (   Stack == []
    ->  ctx_precedences(Ctx, Precedences)
    ;   Precedences = []
    ),
    map_list_to_pairs(criticality_key(Domain, Precedences), Goals, Pairs),
    keysort(Pairs, Sorted),
    pairs_values(Sorted, Ordered).

criticality_key(Domain, Precedences, Goal, Weight-Rank) :-
    goal_criticality(Domain, Goal, Weight0),
    Weight is -Weight0,
    (   Precedences == []
    ->  Rank = 0
    ;   successor_depth(Precedences, Goal, [], Depth),
        Rank is -Depth
    ).

successor_depth(Precedences, Goal, Seen, Depth) :-
    aggregate_all(max(D),
                  ( member(G-After, Precedences),
                    G == Goal,
                    \+ memberchk(After, Seen),
                    successor_depth(Precedences, After, [Goal|Seen], D0),
                    D is D0 + 1
                  ),
                  Depth0),
    !,
    Depth = Depth0.
successor_depth(_, _, _, 0).

%   achieve(+Goal, +Siblings, +Stack, +Ctx, +State0, -State, +Done0, -Done)
%
%   Achieve Goal, which does not hold in State0, by one establisher whose preconditions
%   are achieved first.  Siblings are the goals Goal is achieved together with.

achieve(Goal, Siblings, Stack, Ctx, State0, State, Done0, Done) :-
    ctx_depth(Ctx, MaxDepth),
    length(Stack, Depth),
    Depth < MaxDepth,
    \+ ( member(Above, Stack), Above =@= Goal ),
    establishers(Goal, Siblings, Stack, Ctx, State0, Candidates),
    member(Goal-Op, Candidates),
    tick(Ctx),
    debug(planner(achieve), '~*c~p by ~p', [Depth, 0' , Goal, Op]),
    Op = op(_Action, Pre, _Add, _Del, _Unary, Nary, _Res),
    ctx_rounds(Ctx, Rounds),
    length(Pre, NPre),
    PreRounds is Rounds*NPre + 1,
    achieve_all(Pre, [Goal|Stack], Ctx, PreRounds, State0, State1, Done0, Done1),
    maplist(check_constraint(Ctx, final), Nary),
    apply_op(Ctx, Op, State1, State),
    memberchk(Goal, State),
    Done = [Op|Done1].

%   establishers(+Goal, +Siblings, +Stack, +Ctx, +State, -Candidates) is det.
%
%   Candidates are Goal-Op pairs: the operator instances Op that add Goal, their
%   variables bound by the state and the unary constraints and tested by the n-ary
%   constraints, best first, each with Goal as that instance binds it.

establishers(Goal, Siblings, Stack, Ctx, State, Candidates) :-
    ctx_domain(Ctx, Domain),
    relaxed_state_costs(Ctx, State, Costs),
    protected_facts(Siblings, Stack, Ctx, State, Protected),
    findall(Score-(Goal-Op),
            candidate(Goal, Stack, Ctx, Domain, State, Costs, Protected, Op, Score),
            Pairs0),
    sort(Pairs0, Pairs1),                  % same candidate found twice
    keysort(Pairs1, Pairs),
    pairs_values(Pairs, Candidates).

candidate(Goal, Stack, Ctx, Domain, State, Costs, Protected, Op, Score) :-
    domain_achiever(Domain, Goal, Op),
    Op = op(_, Pre, _, _, Unary, Nary, _),
    bind_by_state(Pre, State),
    maplist(check_constraint(Ctx, generate), Unary),
    maplist(check_constraint(Ctx, generate), Nary),
    top_goal_constraints(Stack, Ctx),
    score(Op, Ctx, State, Costs, Protected, Score).

%   bind_by_state(+Preconditions, +State) is nondet.
%
%   Bind the variables of preconditions that match facts of State (each match is an
%   alternative), or leave them for the constraints to generate.

bind_by_state([], _).
bind_by_state([P|Ps], State) :-
    (   ground(P)
    ->  true
    ;   member(P, State)
    ;   true
    ),
    bind_by_state(Ps, State).

top_goal_constraints([], Ctx) :- !,
    ctx_constraints(Ctx, Constraints),
    maplist(check_constraint(Ctx, generate), Constraints).
top_goal_constraints(_, _).

goal_constraints_hold(Ctx) :-
    ctx_constraints(Ctx, Constraints),
    maplist(check_constraint(Ctx, final), Constraints).

%   protected_facts(+Siblings, +Stack, +Ctx, +State, -Protected)
%
%   The ground sibling goals and top-level goals that hold now: a candidate that would
%   deny one of them is tried after those that do not.

protected_facts(Siblings, Stack, Ctx, State, Protected) :-
    ctx_top_goals(Ctx, Top),
    append(Siblings, Stack, Local),
    append(Local, Top, All),
    include(holds_ground(State), All, Protected0),
    sort(Protected0, Protected).

holds_ground(State, Fact) :-
    ground(Fact),
    memberchk(Fact, State).

%   score(+Op, +Ctx, +State, +Costs, +Protected, -Score)
%
%   Score is Estimate + 2*Penalty: Estimate is the cost of the step's preconditions
%   (relaxed cost when the domain has a relaxation, else the number that do not hold),
%   Penalty the number of protected facts the step would deny (each costs at least
%   two steps to restore).  Unreachable preconditions fail.

score(Op, Ctx, State, Costs, Protected, Score) :-
    Op = op(_, Pre, Add, Del, _, _, _),
    precondition_cost(Pre, State, Costs, 0, Estimate),
    ctx_domain(Ctx, Domain),
    denied_count(Domain, Add, Del, Protected, Penalty),
    Score is Estimate + 2*Penalty.

precondition_cost([], _, _, Cost, Cost).
precondition_cost([P|Ps], State, Costs, Cost0, Cost) :-
    fact_cost(P, State, Costs, C),
    Cost1 is Cost0 + C,
    precondition_cost(Ps, State, Costs, Cost1, Cost).

fact_cost(P, State, Costs, Cost) :-
    (   ground(P)
    ->  (   memberchk(P, State)
        ->  Cost = 0
        ;   Costs = costs(Index, Array)
        ->  get_assoc(P, Index, Id),          % no step can ever add P: fail
            arg(Id, Array, Cost),
            Cost < 1000000
        ;   Cost = 1
        )
    ;   \+ \+ memberchk(P, State)
    ->  Cost = 0
    ;   Cost = 1
    ).

denied_count(_, _, _, [], 0) :- !.
denied_count(Domain, Add, Del, Protected, Count) :-
    aggregate_all(count,
                  ( member(Fact, Protected),
                    \+ memberchk(Fact, Add),
                    denies(Domain, Add, Del, Fact)
                  ),
                  Count).


                 /*******************************
                 *          CONSTRAINTS         *
                 *******************************/

%   check_constraint(+Ctx, +When, +Constraint) is nondet.
%
%   When is `generate` while choosing bindings (a comparison that is not yet ground is
%   left for later) or `final` when the step is applied (every comparison is tested).

check_constraint(Ctx, When, Constraint) :-
    (   comparison(Constraint)
    ->  (   ground(Constraint)
        ->  call(Constraint)
        ;   When == generate
        ->  true
        ;   identity_test(Constraint)
        ->  call(Constraint)
        ;   instantiation_error(Constraint)
        )
    ;   static_fact(Ctx, Constraint)
    ).

%!  constraints_hold(+Domain, +Facts:list, +Constraints:list) is nondet.
%
%   Constraints hold in Domain's static facts and Facts; fact constraints bind their
%   variables, comparisons are tested (they must be ground by then, except the identity
%   tests ==, \==, \= and dif/2).

constraints_hold(Domain, Facts, Constraints) :-
    must_be(list, Facts),
    must_be(list, Constraints),
    Ctx = ctx(Domain, _, _, _, _, _, _, Facts, []),
    maplist(check_constraint(Ctx, final), Constraints).

comparison(_ =< _).
comparison(_ < _).
comparison(_ >= _).
comparison(_ > _).
comparison(_ =:= _).
comparison(_ =\= _).
comparison(_ == _).
comparison(_ \== _).
comparison(_ \= _).
comparison(dif(_, _)).

identity_test(_ == _).
identity_test(_ \== _).
identity_test(_ \= _).
identity_test(dif(_, _)).

static_fact(Ctx, Fact) :-
    ctx_facts(Ctx, Extra),
    ctx_domain(Ctx, planning_domain(_, _, _, _, FactSource, _)),
    (   member(Fact, Extra)
    ;   source_fact(FactSource, Fact)
    ).

source_fact(fact_source(Index, _), Fact) :-
    functor(Fact, Name, Arity),
    get_assoc(Name/Arity, Index, Facts),
    member(Fact, Facts).
source_fact(fact_source(_, Module), Fact) :-
    Module \== none,
    Module:domain_fact(Fact).


                 /*******************************
                 *      APPLYING OPERATORS      *
                 *******************************/

%!  apply_action(+Domain, +Action, +State0:list, -State:list) is semidet.
%
%   State is State0 after the step Action (an instance of an operator of Domain, whose
%   preconditions hold in State0): the facts its adders deny, by deductive operators
%   and deleters, are gone and its adders hold.  Fails if a precondition does not hold.
%   Constraints are not checked.

apply_action(Domain, Action, State0, State) :-
    must_be(callable, Action),
    must_be(list, State0),
    sort(State0, Sorted),
    once(domain_operator(Domain, Action, Op)),
    Op = op(_, Pre, _, _, _, _, _),
    forall(member(P, Pre), memberchk(P, Sorted)),
    apply_op_domain(Domain, Op, Sorted, State).

apply_op(Ctx, Op, State0, State) :-
    ctx_domain(Ctx, Domain),
    apply_op_domain(Domain, Op, State0, State).

apply_op_domain(Domain, op(_, _, Add, Del, _, _, _), State0, State) :-
    denial_patterns(Domain, Add, Del, Patterns),
    (   Patterns == []
    ->  Kept = State0
    ;   exclude(denied_by(Patterns), State0, Kept)
    ),
    sort(Add, AddSet),
    ord_union(Kept, AddSet, State).

%   denial_patterns(+Domain, +Adders, +Deleters, -Patterns)
%
%   The patterns of the facts a step denies: its deleters and the denied propositions
%   of the deductive operators of its adders.

denial_patterns(Domain, Add, Del, Patterns) :-
    Domain = planning_domain(_, _, Deductions, _, _, _),
    findall(pattern(D, []), member(D, Del), DelPatterns),
    findall(Pattern,
            ( member(A, Add),
              member(deduction(Head, HeadPatterns), Deductions),
              copy_term(Head-HeadPatterns, A-Patterns1),
              member(Pattern, Patterns1)
            ),
            Deduced),
    append(DelPatterns, Deduced, Patterns).

denied_by(Patterns, Fact) :-
    member(pattern(P, Conditions), Patterns),
    \+ \+ ( P = Fact, maplist(call, Conditions) ),
    !.

%   denies(+Domain, +Adders, +Deleters, +Fact) is semidet.
%
%   Fact stops holding when a step with Adders and Deleters is applied.

denies(Domain, Add, Del, Fact) :-
    (   member(D, Del),
        D =@= Fact
    ->  true
    ;   Domain = planning_domain(_, _, Deductions, _, _, _),
        Deductions \== [],
        member(A, Add),
        A \== Fact,
        deduction_denies(Deductions, A, Fact)
    ->  true
    ).

deduction_denies(Deductions, Added, Fact) :-
    member(deduction(Head, Patterns), Deductions),
    \+ \+ ( Head = Added,
            member(pattern(Fact0, Conditions), Patterns),
            Fact0 = Fact,
            maplist(call, Conditions) ).


                 /*******************************
                 *       DOMAIN COMPILATION     *
                 *******************************/

%!  compile_domain(+Spec, -Domain) is det.
%
%   Domain is the planner's form of the operators of Spec:
%
%     - module(Module): static_operator/2, deductive_operator/2, criticality/2 (if
%       defined) and domain_fact/1 (if defined) of Module
%     - operators(Operators, Deductive, Options): Operators a list of
%       `static_operator(Name, Fields)`, Deductive a list of
%       `deductive_operator(Name, Fields)`; Options may hold
%       `criticalities(ListOfPatternWeight)`, `facts(StaticFacts)` and
%       `relaxed(Relaxation)` (see relaxed_costs/3)
%
%   @error domain_error(operator_spec, Spec) for anything else

compile_domain(module(Module), Domain) :- !,
    must_be(atom, Module),
    findall(static_operator(N, D), Module:static_operator(N, D), Operators),
    findall(deductive_operator(N, D), Module:deductive_operator(N, D), Deductive),
    (   current_predicate(Module:criticality/2)
    ->  findall(P-W, Module:criticality(P, W), Crits)
    ;   Crits = []
    ),
    (   current_predicate(Module:domain_fact/1)
    ->  FactModule = Module
    ;   FactModule = none
    ),
    build_domain(Operators, Deductive, Crits, [], FactModule, none, Domain).
compile_domain(operators(Operators, Deductive, Options), Domain) :- !,
    must_be(list, Operators),
    must_be(list, Deductive),
    option(criticalities(Crits), Options, []),
    option(facts(Facts), Options, []),
    option(relaxed(Relaxed), Options, none),
    build_domain(Operators, Deductive, Crits, Facts, none, Relaxed, Domain).
compile_domain(Spec, _) :-
    domain_error(operator_spec, Spec).

build_domain(Operators, Deductive, Crits, Facts, FactModule, Relaxed,
             planning_domain(Ops, Achievers, Deductions, Crits,
                             fact_source(FactIndex, FactModule), Relaxed)) :-
    maplist(operator_term, Operators, Ops),
    achiever_index(Ops, Achievers),
    maplist(deduction_term, Deductive, Deductions),
    fact_index(Facts, FactIndex).

operator_term(static_operator(Action, Fields),
              op(Action, Pre, Add, Del, Unary, Nary, Res)) :-
    must_be(callable, Action),
    must_be(list, Fields),
    field(preconditions, Fields, Pre),
    field(adders, Fields, Add),
    field(deleters, Fields, Del),
    field(unary_constraints, Fields, Unary),
    field(n_ary_constraints, Fields, Nary),
    field(resources, Fields, Res).

field(Name, Fields, Value) :-
    Term =.. [Name, Value0],
    (   memberchk(Term, Fields)
    ->  must_be(list, Value0),
        Value = Value0
    ;   Value = []
    ).

achiever_index(Ops, Index) :-
    findall(Key-achiever(Adder, Op),
            ( member(Op, Ops),
              Op = op(_, _, Add, _, _, _, _),
              member(Adder, Add),
              fact_key(Adder, Key)
            ),
            Pairs0),
    keysort(Pairs0, Pairs),
    group_pairs_by_key(Pairs, Groups),
    list_to_assoc(Groups, Index).

fact_key(Fact, Name/Arity) :-
    functor(Fact, Name, Arity).

deduction_term(deductive_operator(Head, Fields), deduction(Head, Patterns)) :-
    must_be(callable, Head),
    field(denied, Fields, Denied),
    maplist(denial_pattern, Denied, Patterns).

%   A denied proposition with neq(X) arguments becomes a pattern with a fresh variable
%   in that place and the condition that the variable is not X.

denial_pattern(Denied, pattern(Pattern, Conditions)) :-
    Denied =.. [Name|Args0],
    foldl(neq_argument, Args0, Args, [], Conditions),
    Pattern =.. [Name|Args].

neq_argument(Arg0, Arg, Conds0, Conds) :-
    (   nonvar(Arg0),
        Arg0 = neq(X)
    ->  Conds = [Arg \== X|Conds0]
    ;   Arg = Arg0,
        Conds = Conds0
    ).

fact_index(Facts, Index) :-
    must_be(list(ground), Facts),
    map_list_to_pairs(fact_key, Facts, Pairs0),
    keysort(Pairs0, Pairs),
    group_pairs_by_key(Pairs, Groups),
    list_to_assoc(Groups, Index).

%!  domain_operator(+Domain, ?Action, -Operator) is nondet.
%
%   Operator is a fresh `op(Action, Pre, Add, Del, Unary, Nary, Resources)` of Domain
%   whose action unifies with Action.

domain_operator(Domain, Action, Op) :-
    Domain = planning_domain(Ops, _, _, _, _, _),
    member(Op0, Ops),
    copy_term(Op0, Op),
    Op = op(Action, _, _, _, _, _, _).

domain_achiever(planning_domain(_, Achievers, _, _, _, _), Goal, Op) :-
    fact_key(Goal, Key),
    get_assoc(Key, Achievers, List),
    member(Achiever, List),
    copy_term(Achiever, achiever(Goal, Op)).

goal_criticality(planning_domain(_, _, _, Crits, _, _), Goal, Weight) :-
    (   member(Pattern-Weight0, Crits),
        subsumes_term(Pattern, Goal)
    ->  Weight = Weight0
    ;   Weight = 0
    ).


                 /*******************************
                 *         PARTIAL ORDER        *
                 *******************************/

%!  partial_order(+Domain, +Actions:list, -Plan:list) is det.
%
%   Plan is the nonlinear form of the executable sequence Actions: one
%   `step(N, Action, Predecessors)` per action, numbered in sequence order, where
%   Predecessors are the immediate predecessors.  Step J precedes step K when K needs
%   or denies what J adds, J needs or denies what K denies or adds, or both use one
%   resource.

partial_order(Domain, Actions, Plan) :-
    must_be(list, Actions),
    maplist(domain_step(Domain), Actions, Ops),
    partial_order_ops(Domain, Ops, Plan).

partial_order_ops(Domain, Ops, Plan) :-
    numbered(Ops, 1, Numbered),
    orderings(Domain, Numbered, Before),
    transitive_reduction(Numbered, Before, Plan).

domain_step(Domain, Action, Op) :-
    (   domain_operator(Domain, Action, Op)
    ->  true
    ;   existence_error(operator, Action)
    ).

numbered([], _, []).
numbered([Op|Ops], N, [N-Op|Rest]) :-
    N1 is N + 1,
    numbered(Ops, N1, Rest).

% Before: list of K-Js, the steps J < K that must precede K.
orderings(Domain, Numbered, Before) :-
    findall(K-Js,
            ( member(K-OpK, Numbered),
              findall(J, ( member(J-OpJ, Numbered),
                           J < K,
                           interacts(Domain, OpJ, OpK)
                         ), Js)
            ),
            Before).

interacts(Domain, op(_, PreJ, AddJ, DelJ, _, _, ResJ), op(_, PreK, AddK, DelK, _, _, ResK)) :-
    (   member(P, PreK), memberchk(P, AddJ)                 % J produces for K
    ->  true
    ;   member(R, ResJ), memberchk(R, ResK)                 % shared resource
    ->  true
    ;   member(P, PreJ), denies(Domain, AddK, DelK, P)      % K clobbers J's need
    ->  true
    ;   member(P, PreK), denies(Domain, AddJ, DelJ, P)      % J clobbers K's need
    ->  true
    ;   member(P, AddJ), denies(Domain, AddK, DelK, P)      % K undoes J
    ->  true
    ;   member(P, AddK), denies(Domain, AddJ, DelJ, P)      % J denies what K adds
    ).

transitive_reduction(Numbered, Before, Plan) :-
    list_to_assoc(Before, BeforeIndex),
    foldl(ancestors(BeforeIndex), Numbered, [], AncestorPairs),
    list_to_assoc(AncestorPairs, Ancestors),
    maplist(reduced_step(BeforeIndex, Ancestors), Numbered, Plan).

ancestors(BeforeIndex, K-_, Acc0, [K-All|Acc0]) :-
    get_assoc(K, BeforeIndex, Js),
    list_to_assoc(Acc0, Known),
    foldl(add_ancestors(Known), Js, Js, All0),
    sort(All0, All).

add_ancestors(Known, J, Acc0, Acc) :-
    get_assoc(J, Known, As),
    append(As, Acc0, Acc).

reduced_step(BeforeIndex, Ancestors, K-op(Action, _, _, _, _, _, _), step(K, Action, Preds)) :-
    get_assoc(K, BeforeIndex, Js),
    exclude(implied(Js, Ancestors), Js, Preds).

implied(Js, Ancestors, J) :-
    member(I, Js),
    I \== J,
    get_assoc(I, Ancestors, As),
    memberchk(J, As), !.


                 /*******************************
                 *     RELAXED COST ESTIMATE    *
                 *******************************/

%!  relaxed_costs(+Relaxed, +State:list, -Costs) is det.
%
%   Costs is `costs(Index, Array)`: the additive relaxed cost (delete lists ignored,
%   each step costing 1 plus the costs of its preconditions) of every fact of the
%   grounded relaxation Relaxed from State; Index maps a fact to its argument of Array;
%   1000000 stands for unreachable.  Relaxed is
%   `relaxed(Index, NFacts, Pre, Add, PreOf, Free)`: Pre and Add are terms whose
%   arguments are the fact-number lists of each ground action, PreOf the term whose
%   arguments are the actions needing each fact, Free the actions without
%   preconditions.

relaxed_costs(relaxed(Index, NFacts, Pre, Add, PreOf, Free), State, costs(Index, Costs)) :-
    compound_name_arity(Pre, _, NActs),
    filled(NFacts, 1000000, Costs),
    filled(NActs, 0, Waiting),
    filled(NActs, 0, Sum),
    forall(between(1, NActs, A),
           ( arg(A, Pre, Ps), length(Ps, L), nb_setarg(A, Waiting, L) )),
    state_ids(State, Index, Ids),
    forall(member(F, Ids), nb_setarg(F, Costs, 0)),
    enable(Free, Add, Sum, Costs, [], Reached0),
    append(Ids, Reached0, Layer0),
    relax_layers(Layer0, Pre, Add, PreOf, Waiting, Sum, Costs).

filled(N, Value, Term) :-
    functor(Term, a, N),
    forall(between(1, N, I), nb_setarg(I, Term, Value)).

state_ids([], _, []).
state_ids([Fact|Facts], Index, Ids) :-
    (   get_assoc(Fact, Index, Id)
    ->  Ids = [Id|Rest]
    ;   Ids = Rest
    ),
    state_ids(Facts, Index, Rest).

relax_layers([], _, _, _, _, _, _) :- !.
relax_layers(Layer, Pre, Add, PreOf, Waiting, Sum, Costs) :-
    foldl(release(PreOf, Waiting, Sum, Costs), Layer, [], Enabled),
    enable(Enabled, Add, Sum, Costs, [], Next),
    relax_layers(Next, Pre, Add, PreOf, Waiting, Sum, Costs).

release(PreOf, Waiting, Sum, Costs, Fact, Enabled0, Enabled) :-
    arg(Fact, PreOf, Actions),
    arg(Fact, Costs, C),
    foldl(release_action(Waiting, Sum, C), Actions, Enabled0, Enabled).

release_action(Waiting, Sum, C, A, Enabled0, Enabled) :-
    arg(A, Waiting, W0),
    W is W0 - 1,
    nb_setarg(A, Waiting, W),
    arg(A, Sum, S0),
    S is S0 + C,
    nb_setarg(A, Sum, S),
    (   W =:= 0
    ->  Enabled = [A|Enabled0]
    ;   Enabled = Enabled0
    ).

enable([], _, _, _, Reached, Reached).
enable([A|As], Add, Sum, Costs, Reached0, Reached) :-
    arg(A, Sum, S),
    C is S + 1,
    arg(A, Add, Facts),
    foldl(lower_cost(Costs, C), Facts, Reached0, Reached1),
    enable(As, Add, Sum, Costs, Reached1, Reached).

lower_cost(Costs, C, F, Reached0, Reached) :-
    arg(F, Costs, C0),
    (   C < C0
    ->  nb_setarg(F, Costs, C),
        (   C0 =:= 1000000
        ->  Reached = [F|Reached0]
        ;   Reached = Reached0
        )
    ;   Reached = Reached0
    ).

%   relaxed_state_costs(+Ctx, +State, -Costs)
%
%   The relaxed costs from State, remembered for the last state asked about; `none`
%   when the domain has no relaxation.

relaxed_state_costs(Ctx, State, Costs) :-
    ctx_domain(Ctx, planning_domain(_, _, _, _, _, Relaxed)),
    (   Relaxed == none
    ->  Costs = none
    ;   ctx_cache(Ctx, Cache),
        arg(1, Cache, Last),
        Last == State
    ->  arg(2, Cache, Costs)
    ;   relaxed_costs(Relaxed, State, Costs),
        ctx_cache(Ctx, Cache),
        nb_setarg(1, Cache, State),
        nb_setarg(2, Cache, Costs)
    ).
