:- module(faults,
          [ exception/2,                % ?Exception, ?Description
            cause/2,                    % ?Cause, ?Description
            raises/3,                   % ?Cause, ?Exception, ?Likelihood
            prior/2,                    % ?Cause, ?Weight
            test/3,                     % ?Test, ?Description, ?Seconds
            test_needs/2,               % ?Test, ?Preconditions
            predicts/3,                 % ?Test, ?Cause, ?Outcome
            outcome/2,                  % +Test, ?Outcome
            recovery/2,                 % ?Cause, ?Actions
            recovery_goal/1,            % ?Goal
            holds_now/1,                % +Condition
            world_update/1,             % +Change
            recovery_way/3,             % +Repair, +Replan, -Way
            candidate_causes/3,         % +Exception, +Context, -Causes
            instantiate_cause/3,        % +Cause, +Context, -Instance
            test_outcome/4,             % +Test, +Cause, +Context, -Outcome
            isolated/4                  % +Exception, +Context, +Results, -Cause
          ]).

/** <module> Fault diagnosis knowledge: exceptions, causes, tests and recoveries

The Exception Handler's knowledge base (the seed: "a knowledge base ... containing
information about possible causes for each fault, the number of times each exception
has occurred, the assertions that each available test can verify, preconditions of each
test, and an estimated cost for each test").  It is read like kb/operators.pl:

  * exception/2: what the devices and the executive can report (an exception reply, a
    time-out, a reading the part and the instrument make implausible);
  * cause/2 and raises(Cause, Exception, Likelihood): what can be behind each exception,
    and how often it shows that way (P(exception | cause));
  * prior(Cause, Weight): the stated prior of each cause (pseudo-counts; the counts
    learned across runs are added to them by the engine, prolog/diagnosis.pl);
  * test(Test, Description, Seconds): the tests the cell can run, with their own cost in
    simulated seconds (from the same dwell, scan and motion times a run uses; moving to
    the test's place and changing tools is priced by the caller from the arm's state);
    test_needs(Test, Preconditions): what the test needs (`holding(ToolType)`,
    `at(Place)`, `failed_measurement`); predicts(Test, Cause, Outcome): the outcome the
    test gives when Cause holds (`ok` unless listed): the assertions it verifies;
  * recovery(Cause, Actions): how the world model and the cell are put right once the
    cause is isolated: world-model changes, and goals of kb/operators.pl that the
    Operation Planner plans and the Plan Executive runs on the devices (the cell's own,
    or a person called to the cell: a device too).  A new recovery is written here
    alone, with an operator in kb/operators.pl (and a device command) only when the
    cell needs an action it does not have.

Causes are terms over the *context* of an exception, a list of `Key=Value`: the tool in
hand (`probe=P` or `slra=S`), the device (`device=D`).  A cause such as
`broken_probe(probe)` names the context key whose value fills it in
(instantiate_cause/3).  Nothing runs at load time.
*/

:- use_module(library(error)).
:- use_module(library(lists)).
:- use_module(library(apply)).
:- use_module(library(pairs)).
:- use_module(world, []).
:- use_module(operators, []).


                 /*******************************
                 *           EXCEPTIONS         *
                 *******************************/

%!  exception(?Exception, ?Description) is nondet.
%
%   Exception is a kind of exception the devices or the executive report.

exception(no_echo,                 'the gauge saw no back-wall echo').
exception(no_couplant_film,        'only the probe-face echo came back: no couplant film').
exception(doubled_thickness,       'a thickness about twice the nominal').
exception(implausible_thickness,   'a thickness the part and the gauge make implausible').
exception(misaligned,              'the probe face is tilted: the echo walks off').
exception(no_contact,              'the probe did not touch the part').
exception(corrupt_reply,           'a reply that makes no sense').
exception(bump,                    'unplanned contact of the arm or its tool').
exception(controller_timeout,      'the robot controller did not answer in time').
exception(no_path,                 'no collision-free path for the arm').
exception(out_of_view,             'a patch the measurement needs is outside the frame').
exception(too_few_pixels,          'too few valid pixels or edge points in the frame').
exception(fit_residual,            'a fit does not match the range image').
exception(range_image_implausible, 'the range image makes no sense').
exception(view_not_measurable,     'the nominal part leaves nothing in the view to measure the feature on').
exception(tool_not_seated,         'the tool did not latch on pick-up').
exception(position_drift_detected, 'the arm is not where it says it is').


                 /*******************************
                 *             CAUSES           *
                 *******************************/

%!  cause(?Cause, ?Description) is nondet.
%
%   Cause is a possible cause of exceptions; an argument names the context key that
%   fills it in (instantiate_cause/3).

cause(broken_probe(probe),          'the probe in hand is broken (dead element)').
cause(worn_probe(probe),            'the probe in hand is worn (locks on the second echo)').
cause(dry_couplant(probe),          'the dispenser of the probe in hand is dry').
cause(empty_couplant_station,       'the couplant station is empty').
cause(couplant_missed,              'the couplant landed beside the contact point (an approach tilted off the normal)').
cause(controller_not_answering,     'the robot controller is not answering').
cause(sensor_cable_fault(device),   'the sensor or its cable is faulty').
cause(arm_drift,                    'the arm has drifted from its calibration').
cause(part_displaced,               'the part has moved on the fixture').
cause(obstacle,                     'an obstacle is in the cell').
cause(obstacle_at_arm,              'an obstacle against the arm where it stands: every move from there bumps').
cause(dirty_window(slra),           'the window of the SLRA in hand is dirty').
cause(slra_failed(slra),            'the laser or detector of the SLRA in hand has failed (cleaning does not cure it)').
cause(occlusion,                    'something hides the feature from this view').
cause(view_cannot_measure,          'the planned views cannot measure the feature (the part clips or hides it; no fault)').
cause(out_of_tolerance,             'the part itself is out of tolerance there').
cause(thin_section,                 'the section is thinner than the probe can read').
cause(tool_missing(tool),           'the tool is not in its rack slot').
cause(transient_glitch,             'a one-off glitch that a retry clears').
cause(tilted_probe(probe),          'the probe in hand sits crooked in its holder (knocked): its face meets the part tilted').

%!  raises(?Cause, ?Exception, ?Likelihood) is nondet.
%
%   Cause shows as Exception with probability Likelihood (P(Exception | Cause)).

raises(broken_probe(probe),        no_echo,                 0.9).
raises(sensor_cable_fault(device), no_echo,                 0.3).
raises(arm_drift,                  no_echo,                 0.1).
raises(transient_glitch,           no_echo,                 0.2).
raises(dry_couplant(probe),        no_couplant_film,        0.9).
raises(empty_couplant_station,     no_couplant_film,        0.9).
raises(transient_glitch,           no_couplant_film,        0.2).
raises(couplant_missed,            no_couplant_film,        0.9).
raises(worn_probe(probe),          doubled_thickness,       0.9).
raises(thin_section,               doubled_thickness,       0.9).
raises(out_of_tolerance,           implausible_thickness,   0.9).
raises(sensor_cable_fault(device), implausible_thickness,   0.2).
raises(worn_probe(probe),          implausible_thickness,   0.1).
raises(arm_drift,                  misaligned,              0.6).
raises(part_displaced,             misaligned,              0.6).
raises(tilted_probe(probe),        misaligned,              0.9).
raises(arm_drift,                  no_contact,              0.4).
raises(part_displaced,             no_contact,              0.6).
raises(sensor_cable_fault(device), corrupt_reply,           0.9).
raises(transient_glitch,           corrupt_reply,           0.3).
raises(obstacle,                   bump,                    0.9).
raises(obstacle_at_arm,            bump,                    0.9).
raises(arm_drift,                  bump,                    0.2).
raises(part_displaced,             bump,                    0.3).
raises(obstacle,                   no_path,                 0.5).
raises(controller_not_answering,   controller_timeout,      0.95).
raises(transient_glitch,           controller_timeout,      0.1).
raises(part_displaced,             out_of_view,             0.7).
raises(arm_drift,                  out_of_view,             0.3).
raises(view_cannot_measure,        out_of_view,             0.8).
raises(occlusion,                  out_of_view,             0.3).
raises(view_cannot_measure,        too_few_pixels,          0.5).
raises(view_cannot_measure,        fit_residual,            0.3).
raises(view_cannot_measure,        view_not_measurable,     1.0).
raises(dirty_window(slra),         too_few_pixels,          0.9).
raises(occlusion,                  too_few_pixels,          0.6).
raises(dirty_window(slra),         fit_residual,            0.4).
raises(slra_failed(slra),          too_few_pixels,          0.95).
% a drifted arm (or a moved part) puts the feature off where the window looks for it
raises(arm_drift,                  too_few_pixels,          0.3).
raises(arm_drift,                  fit_residual,            0.3).
raises(part_displaced,             too_few_pixels,          0.2).
raises(part_displaced,             fit_residual,            0.2).
raises(occlusion,                  fit_residual,            0.4).
raises(out_of_tolerance,           fit_residual,            0.2).
raises(sensor_cable_fault(device), range_image_implausible, 0.9).
raises(tool_missing(tool),         tool_not_seated,         0.9).
raises(transient_glitch,           tool_not_seated,         0.2).
raises(arm_drift,                  position_drift_detected, 0.9).
raises(part_displaced,             position_drift_detected, 0.4).

%!  prior(?Cause, ?Weight) is nondet.
%
%   The stated prior of Cause, as pseudo-counts: what the cell's maintenance records
%   say before any run.  The engine adds the counts it learns.

prior(broken_probe(probe),          2).
prior(worn_probe(probe),            3).
prior(dry_couplant(probe),          3).
prior(empty_couplant_station,       3).
prior(couplant_missed,              2).
prior(controller_not_answering,     1).
prior(sensor_cable_fault(device),   1).
prior(arm_drift,                    1).
prior(part_displaced,               1).
prior(obstacle,                     1).
prior(obstacle_at_arm,              1).
prior(dirty_window(slra),           3).
prior(slra_failed(slra),            1).
prior(occlusion,                    2).
prior(view_cannot_measure,          2).
prior(out_of_tolerance,             4).
prior(thin_section,                 1).
prior(tool_missing(tool),           1).
prior(transient_glitch,             2).
prior(tilted_probe(probe),          1).


                 /*******************************
                 *             TESTS            *
                 *******************************/

%!  test(?Test, ?Description, ?Seconds) is nondet.
%
%   Test can be run in the cell; it takes Seconds of simulated time once its
%   preconditions hold (dwell, couplant, scan and short moves of the runs themselves).

test(read_cal_block,           'read the calibration block with the probe in hand',            7.0).
test(check_couplant_station,   'read the couplant station''s level',                           3.0).
test(retry_reading,            'fresh couplant and the reading once more',                     5.0).
test(query_controller,         're-home the arm and query the controller',                    12.0).
test(scan_cal_block,           'scan the calibration block with the SLRA in hand',             2.0).
test(clean_and_scan_cal_block, 'wipe the SLRA''s window, then scan the calibration block',     6.0).
test(rescan_second_standoff,   're-scan the feature from a second stand-off',                  4.0).
test(scan_tool_in_rack,        'look at the tool''s rack slot with the SLRA',                  2.0).
test(measure_reference_feature,'measure tooling hole B, a reference feature of the part',      4.0).
test(recalibrate_and_measure_reference,
                               'touch the arm off on the calibration block, then measure tooling hole B again', 20.0).
test(compare_neighbours,       'compare the reading with the neighbouring measurements',       0.1).

%!  test_needs(?Test, ?Preconditions:list) is nondet.
%
%   What Test needs: `holding(ToolType)` (a tool of that type in hand), `at(Place)` (the
%   arm at a place), `failed_reading(Device)` (the measurement that failed, to retry or
%   re-view it, when it failed on Device: `gauge` or `slra`; a repeat tells nothing of a
%   failure elsewhere, say a controller that did not answer on the way there),
%   `failed_measurement` (the failed measurement's reading, whatever failed).

test_needs(read_cal_block,            [holding(us_tool), at(cal_block)]).
test_needs(check_couplant_station,    [at(couplant_station)]).
test_needs(retry_reading,             [holding(us_tool), failed_reading(gauge)]).
test_needs(query_controller,          []).
test_needs(scan_cal_block,            [holding(slra_tool), at(cal_block)]).
test_needs(clean_and_scan_cal_block,  [holding(slra_tool), at(couplant_station), at(cal_block)]).
test_needs(rescan_second_standoff,    [holding(slra_tool), failed_reading(slra)]).
test_needs(scan_tool_in_rack,         [holding(slra_tool), at(rack)]).
test_needs(measure_reference_feature, [holding(slra_tool), at(reference_feature)]).
test_needs(recalibrate_and_measure_reference, [at(cal_block), holding(slra_tool), at(reference_feature)]).
test_needs(compare_neighbours,        [failed_measurement]).

%!  outcome(+Test, ?Outcome) is nondet.
%
%   Outcome is a possible outcome of Test: `ok`, or what predicts/3 says.

outcome(Test, Outcome) :-
    must_be(atom, Test),
    (   Outcome = ok
    ;   setof(O, C^predicts(Test, C, O), Os),
        member(Outcome, Os),
        Outcome \== ok
    ).

%!  predicts(?Test, ?Cause, ?Outcome) is nondet.
%
%   When Cause holds, Test gives Outcome.  A cause not listed for a test gives `ok`:
%   the test verifies it is not there.

predicts(read_cal_block,  broken_probe(probe),        no_echo).
predicts(read_cal_block,  worn_probe(probe),          doubled).
predicts(read_cal_block,  dry_couplant(probe),        no_couplant).
predicts(read_cal_block,  empty_couplant_station,     no_couplant).
predicts(read_cal_block,  sensor_cable_fault(device), garbage).
predicts(read_cal_block,  arm_drift,                  misaligned).
predicts(read_cal_block,  controller_not_answering,   silent).
predicts(read_cal_block,  tilted_probe(probe),        misaligned).

predicts(check_couplant_station, empty_couplant_station, empty).
predicts(check_couplant_station, controller_not_answering, silent).

predicts(retry_reading,   broken_probe(probe),        fails_again).
predicts(retry_reading,   worn_probe(probe),          fails_again).
predicts(retry_reading,   dry_couplant(probe),        fails_again).
predicts(retry_reading,   empty_couplant_station,     fails_again).
predicts(retry_reading,   couplant_missed,            fails_again).
predicts(retry_reading,   sensor_cable_fault(device), fails_again).
predicts(retry_reading,   arm_drift,                  fails_again).
predicts(retry_reading,   part_displaced,             fails_again).
predicts(retry_reading,   out_of_tolerance,           fails_again).
predicts(retry_reading,   thin_section,               fails_again).
predicts(retry_reading,   controller_not_answering,   silent).
predicts(retry_reading,   tilted_probe(probe),        fails_again).

predicts(query_controller, controller_not_answering,  silent).

predicts(scan_cal_block,  dirty_window(slra),         too_few_pixels).
predicts(scan_cal_block,  sensor_cable_fault(device), garbage).
predicts(scan_cal_block,  controller_not_answering,   silent).
predicts(scan_cal_block,  slra_failed(slra),          too_few_pixels).

% Wiping the window first tells a dirty window (the block then scans well) from a failed
% laser or detector (it still returns nothing).
predicts(clean_and_scan_cal_block, slra_failed(slra),          too_few_pixels).
predicts(clean_and_scan_cal_block, sensor_cable_fault(device), garbage).
predicts(clean_and_scan_cal_block, controller_not_answering,   silent).

predicts(rescan_second_standoff, dirty_window(slra),         fails_again).
predicts(rescan_second_standoff, slra_failed(slra),          fails_again).
predicts(rescan_second_standoff, arm_drift,                  fails_again).
predicts(rescan_second_standoff, sensor_cable_fault(device), fails_again).
predicts(rescan_second_standoff, part_displaced,             fails_again).
predicts(rescan_second_standoff, out_of_tolerance,           fails_again).
predicts(rescan_second_standoff, view_cannot_measure,        fails_again).
predicts(rescan_second_standoff, controller_not_answering,   silent).

predicts(scan_tool_in_rack, tool_missing(tool),       empty_slot).
predicts(scan_tool_in_rack, dirty_window(slra),       unclear).
predicts(scan_tool_in_rack, slra_failed(slra),        unclear).
predicts(scan_tool_in_rack, controller_not_answering, silent).

predicts(measure_reference_feature, part_displaced,   displaced).
predicts(measure_reference_feature, arm_drift,        displaced).
predicts(measure_reference_feature, controller_not_answering, silent).

% The arm touched off on the block first: a drift is gone (the hole is back where it was), a
% moved part is not.
predicts(recalibrate_and_measure_reference, part_displaced,           displaced).
predicts(recalibrate_and_measure_reference, controller_not_answering, silent).

% An obstacle against the stopped arm: a test's own first move bumps too.
predicts(read_cal_block,            obstacle_at_arm, bump).
predicts(check_couplant_station,    obstacle_at_arm, bump).
predicts(retry_reading,             obstacle_at_arm, bump).
predicts(query_controller,          obstacle_at_arm, bump).
predicts(scan_cal_block,            obstacle_at_arm, bump).
predicts(clean_and_scan_cal_block,  obstacle_at_arm, bump).
predicts(scan_tool_in_rack,         obstacle_at_arm, bump).
predicts(measure_reference_feature, obstacle_at_arm, bump).
predicts(recalibrate_and_measure_reference, obstacle_at_arm, bump).

predicts(compare_neighbours, broken_probe(probe),        outlier).
predicts(compare_neighbours, worn_probe(probe),          outlier).
predicts(compare_neighbours, sensor_cable_fault(device), outlier).
predicts(compare_neighbours, thin_section,               outlier).


                 /*******************************
                 *           RECOVERIES         *
                 *******************************/

%!  recovery(?Cause, ?Actions:list) is nondet.
%
%   Once Cause is isolated, Actions put the world model and the cell right, in order.
%   The Exception Handler knows these kinds of action, not the recoveries:
%
%     * `world(Change)`: the world model changes (world_update/1): `tool_condition(Tool,
%       Condition)` (a tool marked: the Sequence Planner resequences to its spare, or
%       leaves its measurements "cannot be done"), `location(Tool, missing)`;
%     * `achieve(Goal)`: Goal is an adder of an operator of kb/operators.pl
%       (recovery_goal/1); the Operation Planner plans it from the arm's state (moving
%       to a station and changing tools as its preconditions need), the Plan Executive
%       runs the plan on the devices.  The cell's own (refill, purge, reset, reseat,
%       recalibrate, clean) and a person's (called to the cell: an obstacle removed, the
%       part re-clamped, a tool replaced from the stores; the run waits) alike.  A
%       variable in Goal is the planner's to bind (the arm: the operator's constraint
%       `type(Arm, arm)`).  When the plan fails, the actions after it are not made;
%     * `unless(Condition, Actions)`: Actions only when Condition does not hold of the
%       world model now, after the actions before (holds_now/1);
%     * `accept(reading)`: the failed reading stands: it is the part, not the instrument;
%     * `accept(test(Test))`: the value Test measured stands (a second stand-off's view of
%       a feature the first one saw occluded);
%     * `retry`: nothing to put right but to try again;
%     * `register(part)`: the part located on its datums again (the tooling holes by
%       the SLRA) and measured where it now sits; not achieved when the cell cannot see
%       them where they are (the part is further off than its views reach);
%     * `first_of(Alternatives)`: the first list of actions of Alternatives that is
%       carried out to its end (a knocked part registered where it lies, else clamped
%       again by a person and registered);
%     * `remeasure(since_check)`: what was measured since the cell's last good interim
%       check against its reference artifacts (kb/tasks.pl interim_check/1) is measured
%       again: the fault may have been there, unseen, since then.
%
%   An empty list: the cause cannot be put right in the cell (the measurement is not done).

recovery(broken_probe(P),           [ world(tool_condition(P, broken)),
                                      unless(spare_left(P), [ achieve(tool_replaced(P)),
                                                              world(tool_condition(P, ok)) ]) ]).
recovery(worn_probe(P),             [ world(tool_condition(P, worn)),
                                      unless(spare_left(P), [ achieve(tool_replaced(P)),
                                                              world(tool_condition(P, ok)) ]) ]).
recovery(dry_couplant(P),           [achieve(dispenser_purged(P))]).
recovery(empty_couplant_station,    [achieve(couplant_refilled(couplant_station))]).
recovery(couplant_missed,           []).
recovery(controller_not_answering,  [achieve(controller_reset(_Arm))]).
recovery(sensor_cable_fault(D),     [achieve(cable_reseated(D))]).
recovery(arm_drift,                 [achieve(arm_calibrated(_Arm)), remeasure(since_check)]).
recovery(part_displaced,            [ first_of([ [register(part)],
                                                 [achieve(part_clamped(part)), register(part)] ]),
                                      remeasure(since_check) ]).
recovery(obstacle,                  [achieve(obstacles_removed(cell))]).
recovery(obstacle_at_arm,           [achieve(obstacles_removed(cell))]).
recovery(dirty_window(S),           [achieve(window_clean(S))]).
recovery(slra_failed(S),            [ world(tool_condition(S, broken)),
                                      unless(spare_left(S), [ achieve(tool_replaced(S)),
                                                              world(tool_condition(S, ok)) ]) ]).
recovery(occlusion,                 [accept(test(rescan_second_standoff))]).
recovery(view_cannot_measure,       []).
recovery(out_of_tolerance,          [accept(reading)]).
recovery(thin_section,              []).
recovery(tool_missing(T),           [world(location(T, missing))]).
recovery(transient_glitch,          [retry]).
recovery(tilted_probe(P),           [achieve(probe_straightened(P))]).

%!  recovery_goal(?Goal) is nondet.
%
%   Goal can be an `achieve(Goal)` of a recovery: some static operator of
%   kb/operators.pl adds it.

recovery_goal(Goal) :-
    operators:static_operator(_, Description),
    memberchk(adders(Adders), Description),
    member(Goal, Adders).

%!  holds_now(+Condition) is semidet.
%
%   Condition of an `unless(Condition, Actions)` recovery action holds of the world
%   model (kb/world.pl) now:
%
%     * spare_left(Tool): another tool of Tool's type is usable (world:usable/3).

holds_now(spare_left(Tool)) :-
    world:type(Tool, Type),
    world:usable(_Arm, Type, Other),
    Other \== Tool,
    !.

%!  world_update(+Change) is det.
%
%   Make the world model (kb/world.pl) say Change, a `world(Change)` of a recovery:
%   `tool_condition(Tool, Condition)` or `location(Tool, Where)`.
%
%   @error domain_error(world_change, Change) for any other change

world_update(tool_condition(Tool, Condition)) :-
    !,
    world:set_tool_condition(Tool, Condition).
world_update(location(Tool, Where)) :-
    !,
    world:set_location(Tool, Where).
world_update(Change) :-
    domain_error(world_change, Change).

%!  recovery_way(+Repair, +Replan, -Way) is det.
%
%   How the measurement is taken again once the cell is put right: Repair and Replan are
%   `steps(N)`, the length of the repaired plan (the failed plan's unfinished steps after
%   a plan for their preconditions) and of a new plan from the arm's state, or `none`
%   when there is no such plan.  Way is `repair` (it keeps the failed plan's work: the
%   seed's authors' wish) unless a new plan is shorter (the unfinished steps begin with
%   moves the arm no longer needs) or there is no repair; `replan` then; `none` when
%   neither exists.

recovery_way(none, none, none) :- !.
recovery_way(none, steps(_), replan) :- !.
recovery_way(steps(_), none, repair) :- !.
recovery_way(steps(R), steps(P), replan) :- P < R, !.
recovery_way(steps(_), steps(_), repair).


                 /*******************************
                 *        WITH A CONTEXT        *
                 *******************************/

%!  instantiate_cause(+Cause, +Context:list, -Instance) is semidet.
%
%   Instance is Cause with its context key filled in from Context (`probe=us_probe_1`
%   turns broken_probe(probe) into broken_probe(us_probe_1)); a cause without an
%   argument is itself.  Fails when Context lacks the key.

instantiate_cause(Cause, Context, Instance) :-
    must_be(list, Context),
    (   compound(Cause)
    ->  Cause =.. [Name, Key],
        memberchk(Key=Value, Context),
        Instance =.. [Name, Value]
    ;   Instance = Cause
    ).

%!  candidate_causes(+Exception, +Context:list, -Causes:list) is det.
%
%   Causes are `Cause-Likelihood` for every cause that raises Exception and that
%   Context can fill in, instantiated, in the order of the rule base.
%
%   @error existence_error(exception, Exception) for an unknown exception

candidate_causes(Exception, Context, Causes) :-
    must_be(atom, Exception),
    (   exception(Exception, _)
    ->  true
    ;   existence_error(exception, Exception)
    ),
    findall(Instance-L,
            ( raises(Cause, Exception, L),
              instantiate_cause(Cause, Context, Instance)
            ),
            Causes).

%!  test_outcome(+Test, +Cause, +Context:list, -Outcome) is det.
%
%   Outcome is what Test gives when the instantiated Cause holds (`ok` unless
%   predicts/3 says otherwise).

test_outcome(Test, Cause, Context, Outcome) :-
    (   predicts(Test, Template, Outcome0),
        instantiate_cause(Template, Context, Cause)
    ->  Outcome = Outcome0
    ;   Outcome = ok
    ).


%!  isolated(+Exception, +Context:list, +Results:list, -Cause) is semidet.
%
%   Cause is the one cause of Exception in Context consistent with every test result of
%   Results (`Test-Outcome`).  For `ita kb why`: its proof shows the causes the
%   exception can have and each test's prediction for the one left, e.g.
%
%       ita kb why "faults:isolated(controller_timeout, [device=controller],
%                                   [query_controller-silent], C)"

isolated(Exception, Context, Results, Cause) :-
    candidate_causes(Exception, Context, Candidates),
    pairs_keys(Candidates, Causes),
    include(agrees_with(Context, Results), Causes, [Cause]).

agrees_with(Context, Results, Cause) :-
    forall(member(Test-Outcome, Results), test_outcome(Test, Cause, Context, Outcome)).
