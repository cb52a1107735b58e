:- module(macrop,
          [ generalize_plan/5,          % +Goals, +State, +Plan, +Options, -Macrop
            macrop_applies/5,           % +Macrop, +Goals, +State, +Options, -Plan
            open_store/1,               % +File
            close_store/1,              % +File
            save_store/1,               % +File
            store_macrops/2,            % +File, -Macrops
            store_counts/4,             % +File, -Lookups, -Hits, -Misses
            add_macrop/3,               % +File, +Macrop, -Id
            clear_store/1,              % +File
            lookup/5,                   % +File, +Goals, +State, +Options, -Plan
            operation_plan/5,           % +File, +Goals, +State, +Options, -Result
            measurement_plan/9,         % +File, +Id, +Kind, +Tool, +Arm, +Pose, +Holding, +Mode, -Reply
            goal_plan/6,                % +File, +Goals, +Arm, +Pose, +Holding, -Reply
            repair_plan/6,              % +File, +Actions, +Arm, +Pose, +Holding, -Reply
            macrop_template/3,          % +File, +Id, -Template
            macrop_rows/2,              % +File, -Rows
            macrop_text/3               % +File, +Id, -Text
          ]).

/** <module> MACROP lookup: the Operation Planner's index over its stores

The seed's Operation Planner tries MACROP lookup before it plans: *MACROP lookup*
compares each MACROP to the goals (each goal must unify with a purpose) and the initial
state (each precondition must match a fact), checks the constraints and returns the plan
with the bindings plugged in.  Shorter plans are tried first.  Plan generalization, which
makes MACROPs, is prolog/macrop_generalize.pl; the store, which keeps them in a file with
their counts, is prolog/macrop_store.pl (both re-exported here, so `macrop` is the
Operation Planner's one entry).

*The index.*  An open store has a lookup index, over its learned MACROPs and the
hand-written ones of kb/macrops.pl.  It holds, besides each MACROP's fields, its
applicability test compiled into a clause (state_candidate/9) when the MACROP is added
or loaded: for the planning state of kb/operators.pl, whose arm is at one pose holding
one tool, the MACROP's at/2 and holding/2 preconditions and its purpose go into the
clause head (so the clauses are indexed on them), its other preconditions are matched
against only the facts of their kind, its constraints are calls to the static facts.

*The facade's entry point.*  measurement_plan/9 is the Operation Planner for one
measurement in a single call with a compact reply: the MACROP's number and the values
of its variables rather than the plan, which the caller plugs into the MACROP's plan
(macrop_template/3), as the seed's lookup "plugs the MACROP with the bindings found".

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
:- use_module(macrop_generalize).
:- use_module(macrop_store).
:- reexport(macrop_generalize, [generalize_plan/5]).
:- reexport(macrop_store, [save_store/1, store_macrops/2, store_counts/4]).
:- use_module('../kb/macrops', []).

:- use_module(library(aggregate)).
:- use_module('../kb/operators',
              [ measurement_goal/5,
                planning_state/4,
                must_be_planning_state/3,
                planning_state_facts/3
              ]).

% The lookup index of a store, in lookup order (fewest steps first, learned first):
:- dynamic candidate/6.         % candidate(File, Id, Purpose, Pre, Constraints, Vars)
:- dynamic candidate_plan/5.    % candidate_plan(File, Id, Vars, Steps, Adders)
% ... and each MACROP's applicability compiled into a clause, for measurement_plan/9:
:- dynamic state_candidate/9.   % state_candidate(File, Goal, Arm, Pose, Holding,
                                %                 GoalConstraints, Id, HitKey, Vars)


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
                 *       STORE AND INDEX        *
                 *******************************/

%!  open_store(+File) is det.
%
%   Load the MACROP store File (an empty store if the file does not exist yet),
%   replacing what was loaded from it before, and index it for lookup.
%
%   @error syntax_error(...) if File is not a readable Prolog file
%   @error domain_error(macrop_store_term(File), Term) for a term that is not a store's

open_store(File) :-
    load_store(File),
    reindex(File).

%!  close_store(+File) is det.
%
%   Forget the store File (without saving it) and its index.

close_store(File) :-
    forget_store(File),
    retractall(candidate(File, _, _, _, _, _)),
    retractall(candidate_plan(File, _, _, _, _)),
    retractall(state_candidate(File, _, _, _, _, _, _, _, _)).

%!  clear_store(+File) is det.
%
%   Forget the learned MACROPs, the hits and the counts of the open store File (the
%   file is unchanged until save_store/1).
%
%   @error existence_error(macrop_store, File) if File is not open

clear_store(File) :-
    reset_store(File),
    reindex(File).

%!  add_macrop(+File, +Macrop, -Id:integer) is det.
%
%   Store Macrop in the open store File under the new number Id, unless a variant of it
%   is there already (then Id is that one's number).

add_macrop(File, macrop(Name, Fields), Id) :-
    store_macrop(File, Name, Fields, Stored),
    (   Stored = new(Id)
    ->  reindex(File)
    ;   Stored = existing(Id)
    ).

%   reindex(+File)
%
%   Rebuild the lookup index of store File: one candidate/6 and one candidate_plan/5
%   clause per MACROP, learned and hand-written, in lookup order.  Vars, the variables
%   of the MACROP's plan and adders, is shared by the two clauses of a MACROP.

reindex(File) :-
    retractall(candidate(File, _, _, _, _, _)),
    retractall(candidate_plan(File, _, _, _, _)),
    retractall(state_candidate(File, _, _, _, _, _, _, _, _)),
    findall(Len-(Id-macrop(Name, Fields)),
            ( stored(File, Id, Name, Fields),
              plan_length(Fields, Len)
            ),
            Learned),
    findall(Len-(kb(Name)-macrop(NameAndFormat, Fields)),
            ( macrops:macrop(NameAndFormat, Fields),
              functor(NameAndFormat, Name, _),
              plan_length(Fields, Len)
            ),
            Written),
    append(Learned, Written, All),
    keysort(All, Sorted),
    pairs_values(Sorted, Candidates),
    forall(member(Id-Macrop, Candidates), index_macrop(File, Id, Macrop)).

index_macrop(File, Id, macrop(_, Fields)) :-
    memberchk(purpose(Purpose), Fields),
    memberchk(preconditions(Pre), Fields),
    memberchk(unary_constraints(Unary), Fields),
    memberchk(n_ary_constraints(Nary), Fields),
    memberchk(plan(Steps), Fields),
    (   memberchk(adders(Adders), Fields) -> true ; Adders = [] ),
    append(Unary, Nary, Constraints),
    term_variables(Steps-Adders, Vars),
    assertz(candidate(File, Id, Purpose, Pre, Constraints, Vars)),
    assertz(candidate_plan(File, Id, Vars, Steps, Adders)),
    (   state_candidate_clause(File, Id, Purpose, Pre, Constraints, Vars, Clause)
    ->  assertz(Clause)
    ;   true
    ).

%   state_candidate_clause(+File, +Id, +Purpose, +Pre, +Constraints, +Vars, -Clause)
%   is semidet.
%
%   Clause is the state_candidate/9 clause of MACROP Id: the test of lookup_bindings/8
%   against the planning state of operators:planning_state/4, with what can be done
%   once done when the MACROP is indexed.  That state holds exactly one at/2 and one
%   holding/2 fact, the arm's, so the preconditions at(A, P) and holding(A, T) are
%   unified with the clause's Arm, Pose and Holding in its head (and the clauses are
%   indexed on them); a purpose of one goal is unified with Goal in the head too.  The
%   other preconditions are matched against only the facts of their kind
%   (operators:planning_state_facts/3), in the state's order.  Each constraint becomes
%   the goal that planner:constraints_hold/3 would run for it in the domain of
%   kb/operators.pl, whose static facts are operators:domain_fact/1.  Fails if the
%   MACROP cannot apply to any such state.

state_candidate_clause(File, Id, Purpose0, Pre0, Constraints0, Vars0,
                       (Head :- Body)) :-
    copy_term(t(Purpose0, Pre0, Constraints0, Vars0),
              t(Purpose, Pre, Constraints, Vars)),
    Head = state_candidate(File, Goal, Arm, Pose, Holding, GoalConstraints, Id, Key, Vars),
    hit_key(File, Id, Key),
    (   Purpose = [Goal]
    ->  PurposeGoals = []
    ;   Purpose \== [],
        PurposeGoals = [lists:member(Goal, Purpose)]
    ),
    foldl(precondition_goal(Arm, Pose, Holding), Pre, PreGoals, []),
    maplist(constraint_goal, Constraints, ConstraintGoals),
    append([PurposeGoals, PreGoals, ConstraintGoals,
            [ macrop:final_constraints(GoalConstraints),
              ground(Vars)
            ]],
           Goals),
    list_conj(Goals, Body).

precondition_goal(Arm, Pose, _, at(A, P), Goals, Goals) :- !,
    A = Arm,
    P = Pose.
precondition_goal(Arm, _, Holding, holding(A, T), Goals, Goals) :- !,
    A = Arm,
    T = Holding.
precondition_goal(_, _, Holding, Fact,
                  [ operators:planning_state_facts(Holding, Fact, Facts),
                    lists:member(Fact, Facts)
                  | Goals ], Goals).

%   constraint_goal(+Constraint, -Goal)
%
%   Goal is what final_constraint/1 does for Constraint, as far as it can be decided
%   before Constraint's variables are bound.

constraint_goal(Constraint, Goal) :-
    (   var(Constraint)
    ->  Goal = macrop:final_constraint(Constraint)
    ;   planner:comparison(Constraint)
    ->  (   planner:identity_test(Constraint)
        ->  Goal = Constraint
        ;   Goal = ( ground(Constraint) -> Constraint ; instantiation_error(Constraint) )
        )
    ;   Goal = operators:domain_fact(Constraint)
    ).

final_constraints([]).
final_constraints([Constraint|Constraints]) :-
    final_constraint(Constraint),
    final_constraints(Constraints).

%   final_constraint(+Constraint) is nondet.
%
%   Constraint holds in the static facts of kb/operators.pl as planner:constraints_hold/3
%   checks it: a comparison must be ground (an identity test need not), any other
%   constraint is a static fact.

final_constraint(Constraint) :-
    (   planner:comparison(Constraint)
    ->  (   ground(Constraint)
        ->  call(Constraint)
        ;   planner:identity_test(Constraint)
        ->  call(Constraint)
        ;   instantiation_error(Constraint)
        )
    ;   operators:domain_fact(Constraint)
    ).

list_conj([], true).
list_conj([G], G) :- !.
list_conj([G|Gs], (G, C)) :-
    list_conj(Gs, C).

plan_length(Fields, Len) :-
    memberchk(plan(Steps), Fields),
    length(Steps, Len).

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
    (   lookup_bindings(File, Goals, State, Domain, Facts, GoalConstraints, Id, Vars)
    ->  candidate_plan(File, Id, Vars, Plan, _),
        Found = found(Id, Plan)
    ;   Found = none
    ).

%   lookup_bindings(+File, +Goals, +State, +Domain, +Facts, +GoalConstraints, -Id, -Vars)
%   is semidet.
%
%   The first MACROP Id of the index of File that achieves Goals from State, and the
%   values Vars of its variables; counts the lookup as a hit or a miss.

lookup_bindings(File, Goals, State, Domain, Facts, GoalConstraints, Id, Vars) :-
    (   candidate(File, Id, Purpose, Pre, Constraints, Vars),
        maplist(in_purpose(Purpose), Goals),
        match_all(Pre, State),
        append(Constraints, GoalConstraints, All),
        constraints_hold(Domain, Facts, All),
        ground(Vars)
    ->  count_lookup(File, hit(Id))
    ;   count_lookup(File, miss),
        fail
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


                 /*******************************
                 *      THE FACADE'S ENTRY      *
                 *******************************/

%!  measurement_plan(+File, +Id, +Kind, +Tool, +Arm, +Pose, +Holding, +Mode, -Reply) is det.
%
%   Pose is a pose term or, flat, `[PoseKind, Place]` or `[PoseKind, PlaceName, Arg]`
%   (e.g. `[in_contact_point, meas, 'WT-1']`).
%
%   The Operation Planner for measurement Id of Kind with Tool, the tool the Sequence
%   Planner chose for it (operators:measurement_goal/5: the goal is
%   `measured(Tool, Arm, meas(Id))`, so every plan and MACROP found uses Tool), from
%   the state of Arm at Pose holding Holding (operators:planning_state/4), with the
%   MACROPs of the open store File.  The lookup finds what lookup/5 finds in that
%   state, through the compiled clauses of the index, without deriving the state.  Mode
%   is `lookup_first` (MACROP lookup; when none applies, plan from scratch, generalize
%   and store) or `from_scratch` (no lookup: plan, generalize and store).  Reply is
%
%     - `[macrop, Generation, MacropId, Bindings]`: a MACROP applies
%     - `[scratch, Generation, MacropId, Bindings]`: planned, stored as MacropId
%     - `[scratch, Generation, none, []]`: the goal holds already (empty plan)
%     - `[no_plan, ReasonText]`
%
%   Bindings are the values of the MACROP's variables in the order of its template
%   (macrop_template/3); Generation changes whenever MACROP numbers of File may be
%   reused (open_store/1, clear_store/1), so a caller may cache templates under
%   Generation-MacropId.  The reply is compact because every atom costs time on its
%   way to Python.
%
%   @error existence_error(macrop_store, File) if File is not open
%   @error domain_error(measurement_kind, Kind) for an unknown kind
%   @error existence_error(tool, Tool) if Tool is not a tool of the world model
%   @error domain_error(tool_for(Kind), Tool) if no tool rule lets Tool measure Kind

measurement_plan(File, Id, Kind, Tool, Arm, PoseSpec, Holding, Mode, Reply) :-
    must_be_open(File),
    (   ( Mode == lookup_first ; Mode == from_scratch )
    ->  true
    ;   must_be(oneof([lookup_first, from_scratch]), Mode)
    ),
    must_be(atom, Tool),
    pose_term(PoseSpec, Pose),
    measurement_goal(Id, Kind, Tool, Goal, Constraints),
    must_be_planning_state(Arm, Pose, Holding),
    store_generation(File, Gen),
    (   Mode == lookup_first,
        state_lookup(File, Goal, Arm, Pose, Holding, Constraints, MacropId, Vars)
    ->  Reply = [macrop, Gen, MacropId, Vars]
    ;   planning_state(Arm, Pose, Holding, State),
        operators_domain(Domain),
        Options = [domain(Domain), constraints(Constraints)],
        plan_result([Goal], State, Options, Result),
        planned_reply(Result, File, Goal, State, Options, Gen, Reply)
    ).

%!  goal_plan(+File, +Goals:list, +Arm, +Pose, +Holding, -Reply) is det.
%
%   The Operation Planner for any goals (the Exception Handler's tests and repairs, e.g.
%   `[calibrated(us_probe_1)]`, `[couplant_refilled(couplant_station)]`) from the state
%   of Arm at Pose holding Holding: MACROP lookup in store File first, else plan,
%   generalize and store (operation_plan/5).  Reply is `[Source, Plan, FinalPose,
%   FinalHolding]` (Source `macrop` or `scratch`, Plan the steps `step(N, Action,
%   Predecessors)`, the arm's pose and tool after it) or `[no_plan, ReasonText]`.
%
%   @error existence_error(macrop_store, File) if File is not open

goal_plan(File, Goals, Arm, PoseSpec, Holding, Reply) :-
    must_be_open(File),
    must_be(list, Goals),
    pose_term(PoseSpec, Pose),
    must_be_planning_state(Arm, Pose, Holding),
    planning_state(Arm, Pose, Holding, State),
    operators_domain(Domain),
    operation_plan(File, Goals, State, [domain(Domain)], Result),
    (   Result = no_plan(Reason)
    ->  format(atom(Text), '~q', [Reason]),
        Reply = [no_plan, Text]
    ;   (   Result = macrop(_, Plan) -> Source = macrop ; Result = planned(_, Plan), Source = scratch ),
        msort(Plan, Ordered),
        foldl(apply_step(Domain), Ordered, State, Final),
        (   memberchk(at(Arm, FinalPose), Final) -> true ; FinalPose = Pose ),
        (   memberchk(holding(Arm, FinalHolding), Final) -> true ; FinalHolding = Holding ),
        Reply = [Source, Plan, FinalPose, FinalHolding]
    ).

%!  repair_plan(+File, +Actions:list, +Arm, +Pose, +Holding, -Reply) is det.
%
%   Plan repair (the seed's authors' wish: reuse what of a failed plan is still valid):
%   Actions are the steps of a failed plan that did not complete, in order, and the arm
%   is now at Pose holding Holding.  When the first of them cannot run from this state,
%   a plan for all its preconditions (so that one achieved on the way is not undone by
%   another) goes before them; the rest are checked by running them on the planning
%   state.  Reply is `[ok, Prefix, FinalPose, FinalHolding]`
%   (Prefix the steps of that plan, `[]` when none is needed) or `[invalid, Text]` when
%   the remaining steps cannot run even so (then replan).
%
%   @error existence_error(macrop_store, File) if File is not open

repair_plan(File, Actions, Arm, PoseSpec, Holding, Reply) :-
    must_be_open(File),
    must_be(list, Actions),
    pose_term(PoseSpec, Pose),
    must_be_planning_state(Arm, Pose, Holding),
    planning_state(Arm, Pose, Holding, State),
    operators_domain(Domain),
    (   Actions = [First|_],
        domain_operator(Domain, First, op(_, Pre, _, _, _, _, _))
    ->  exclude(holds_in(State), Pre, Missing),
        (   Missing == []
        ->  Prefix = [], State1 = State
        ;   operation_plan(File, Pre, State, [domain(Domain)], Result),
            (   Result = macrop(_, Prefix0) -> true ; Result = planned(_, Prefix0) ),
            msort(Prefix0, Prefix),
            foldl(apply_step(Domain), Prefix, State, State1)
        )
    ->  (   catch(foldl(run_action(Domain), Actions, State1, Final), _, fail)
        ->  (   memberchk(at(Arm, FinalPose), Final) -> true ; FinalPose = Pose ),
            (   memberchk(holding(Arm, FinalHolding), Final) -> true ; FinalHolding = Holding ),
            Reply = [ok, Prefix, FinalPose, FinalHolding]
        ;   Reply = [invalid, 'the remaining steps cannot run from the new state']
        )
    ;   Reply = [invalid, 'no plan reaches the preconditions of the first remaining step']
    ).

apply_step(Domain, step(_, Action, _), State0, State) :-
    apply_action(Domain, Action, State0, State).

holds_in(State, Fact) :-
    memberchk(Fact, State).

run_action(Domain, Action, State0, State) :-
    domain_operator(Domain, Action, op(_, Pre, _, _, _, _, _)),
    forall(member(P, Pre), memberchk(P, State0)),
    apply_action(Domain, Action, State0, State).

%   state_lookup(+File, +Goal, +Arm, +Pose, +Holding, +GoalConstraints, -Id, -Vars)
%   is semidet.
%
%   lookup_bindings/8 for the goal Goal from the planning state of Arm at Pose holding
%   Holding (operators:planning_state/4) in the domain of kb/operators.pl, through the
%   compiled clauses of the index; counts the lookup as a hit or a miss.

state_lookup(File, Goal, Arm, Pose, Holding, GoalConstraints, Id, Vars) :-
    (   state_candidate(File, Goal, Arm, Pose, Holding, GoalConstraints, Id, Key, Vars)
    ->  count_hit(File, Id, Key)
    ;   count_lookup(File, miss),
        fail
    ).

planned_reply(plan([]), _, _, _, _, Gen, [scratch, Gen, none, []]) :- !.
planned_reply(plan(Plan), File, Goal, State, Options, Gen, [scratch, Gen, Id, Vars]) :- !,
    generalize_plan([Goal], State, Plan, Options, Macrop),
    add_macrop(File, Macrop, Id),
    candidate_plan(File, Id, Vars, Steps, _),
    maplist(same_action, Steps, Plan),
    must_be(ground, Vars).
planned_reply(no_plan(Reason), _, _, _, _, _, [no_plan, Text]) :-
    format(atom(Text), '~q', [Reason]).

same_action(step(N, Action, _), step(N, Action, _)).

%   pose_term(+PoseSpec, -Pose)
%
%   A pose given flat, `[PoseKind, Place]` or `[PoseKind, PlaceName, PlaceArg]` (fewer
%   JSON objects to cross the bridge), or as the pose term itself.

pose_term([Kind, Place], Pose) :-
    pose_kind(Kind),
    atom(Place),
    !,
    Pose =.. [Kind, Place].
pose_term([Kind, Name, Arg], Pose) :-
    pose_kind(Kind),
    atom(Name),
    atomic(Arg),
    !,
    Place =.. [Name, Arg],
    Pose =.. [Kind, Place].
pose_term([Kind|Place], _) :- !,
    must_be(oneof([approach_point, in_contact_point, viewing_pose]), Kind),
    (   Place = [Name, Arg]
    ->  must_be(atom, Name),
        must_be(atomic, Arg)
    ;   Place = [Name]
    ->  must_be(atom, Name)
    ;   domain_error(pose, [Kind|Place])
    ).
pose_term(Pose, Pose) :-
    must_be(ground, Pose).

pose_kind(approach_point).
pose_kind(in_contact_point).
pose_kind(viewing_pose).

%   operators_domain(-Domain)
%
%   The compiled domain of kb/operators.pl, compiled once per thread and again when
%   the operators change (a reload).

operators_domain(Domain) :-
    operators_generation(Generation),
    (   nb_current(macrop_operators_domain, domain(Generation0, Domain0)),
        Generation0 == Generation
    ->  Domain = Domain0
    ;   compile_domain(module(operators), Domain),
        nb_setval(macrop_operators_domain, domain(Generation, Domain))
    ).

operators_generation(Generation) :-
    aggregate_all(max(G),
                  ( member(Head, [static_operator(_, _), deductive_operator(_, _),
                                  criticality(_, _)]),
                    predicate_property(operators:Head, last_modified_generation(G))
                  ),
                  Generation).

%!  macrop_template(+File, +Id, -Template) is det.
%
%   Template is `template(NVars, Steps, Adders)`: the plan and overall adders of MACROP
%   Id of the open store File with its variables numbered `'$VAR'(0)` to
%   `'$VAR'(NVars-1)` in the order of the Bindings of measurement_plan/9.
%
%   @error existence_error(macrop, Id) if the store has no MACROP Id

macrop_template(File, Id, template(NVars, Steps, Adders)) :-
    must_be_open(File),
    (   candidate_plan(File, Id, Vars, Steps, Adders)
    ->  numbervars(Vars, 0, NVars)
    ;   existence_error(macrop, Id)
    ).

%!  macrop_rows(+File, -Rows:list) is det.
%
%   One row `[Id, Name, Steps, Hits, Purpose]` per MACROP of the open store File, in
%   lookup order: Id a number (learned) or `kb(Name)` (hand-written), Name the functor
%   of its name and format, Steps the length of its plan, Purpose its purpose as text.

macrop_rows(File, Rows) :-
    must_be_open(File),
    findall([Id, Name, Len, Hits, PurposeText],
            ( candidate(File, Id, Purpose, _, _, _),
              macrop_fields(File, Id, NameAndFormat, Fields),
              functor(NameAndFormat, Name, _),
              plan_length(Fields, Len),
              stored_hits(File, Id, Hits),
              term_text(Purpose, PurposeText)
            ),
            Rows).

%   term_text(+Term, -Text): Term written with its variables as A, B, ...

term_text(Term, Text) :-
    copy_term(Term, Copy),
    numbervars(Copy, 0, _),
    format(atom(Text), '~W', [Copy, [quoted(true), numbervars(true), spacing(next_argument)]]).

macrop_fields(_File, kb(Name), NameAndFormat, Fields) :- !,
    macrops:macrop(NameAndFormat, Fields),
    functor(NameAndFormat, Name, _).
macrop_fields(File, Id, NameAndFormat, Fields) :-
    stored(File, Id, NameAndFormat, Fields).

%!  macrop_text(+File, +Id, -Text) is det.
%
%   Text is MACROP Id of the open store File as a Prolog clause
%   `macrop(NameAndFormat, Fields)`, laid out like the seed's Figure 4.
%
%   @error existence_error(macrop, Id) if the store has no MACROP Id

macrop_text(File, Id, Text) :-
    must_be_open(File),
    (   macrop_fields(File, Id, NameAndFormat, Fields)
    ->  copy_term(NameAndFormat-Fields, Copy),
        numbervars(Copy, 0, _),
        with_output_to(string(Text0), write_macrop(Copy)),
        atom_string(Text, Text0)
    ;   existence_error(macrop, Id)
    ).

write_macrop(NameAndFormat-Fields) :-
    Options = [quoted(true), numbervars(true), spacing(next_argument)],
    format('macrop(~W,~n', [NameAndFormat, Options]),
    length(Fields, N),
    forall(nth1(I, Fields, Field),
           ( Field =.. [Key, Items],
             (   I == 1 -> Open = '[ ' ; Open = '  ' ),
             (   I == N -> Close = ' ]).' ; Close = ',' ),
             (   is_list(Items), Items \== []
             ->  format('       ~w~w([ ', [Open, Key]),
                 length(Items, M),
                 forall(nth1(J, Items, Item),
                        (   J == M
                        ->  format('~W ])~w~n', [Item, Options, Close])
                        ;   atom_length(Key, KL),
                            Indent is 7 + 2 + KL + 3,
                            format('~W,~n~*c', [Item, Options, Indent, 0' ])
                        ))
             ;   format('       ~w~w(~W)~w~n', [Open, Key, Items, Options, Close])
             ))).
