:- module(operators,
          [ static_operator/2,          % ?NameAndFormat, ?Description
            deductive_operator/2,       % ?NameAndFormat, ?Description
            operator_field/3,           % ?NameAndFormat, ?Field, ?Value
            criticality/2,              % ?Goal, ?Weight
            domain_fact/1,              % ?Fact
            measurement_goal/5,         % +Id, +Kind, ?Tool, -Goal, -Constraints
            world_state/3,              % +Arm, +Pose, -State
            planning_state/4,           % +Arm, +Pose, +Holding, -State
            must_be_planning_state/3,   % +Arm, +Pose, +Holding
            planning_state_facts/3      % +Holding, ?Pattern, -Facts
          ]).

/** <module> Static and deductive operators of the inspection domain

The operators of the Operation Planner, written so that a reader of the seed's Figure 3
finds each keyword at once.  A static operator is

    static_operator(NameAndFormat,
                    [ preconditions(Facts),      % must hold before the step
                      adders(Facts),             % made true by the step
                      unary_constraints(Goals),  % generate candidate bindings
                      n_ary_constraints(Goals),  % test candidate bindings
                      resources(Objects),        % steps sharing one are ordered
                      message_pattern(Message),  % what the executive sends
                      command_stream(Stream),    % which device stream receives it
                      reply_pattern(Reply),      % what the device answers
                      result_pattern(Result)     % what the step reports
                    ]).

There are no delete lists.  A deductive operator names the propositions that an added
fact denies:

    deductive_operator(holding(Arm, Tool),
                       [ denied([ location(Tool, in_rack(_Slot)),
                                  holding(Arm, neq(Tool)) ]) ]).

An argument `neq(X)` in a denied proposition stands for "any value other than X" (the
figure's `(n= $tool)`); other variables match anything.

The planning state is a list of ground facts:

  | fact                                   | meaning                                     |
  |----------------------------------------|---------------------------------------------|
  | at(Arm, Pose)                          | Arm's tool point is at Pose                 |
  | holding(Arm, Tool)                     | Arm holds Tool; `holding(Arm, none)`: empty |
  | location(Tool, in_rack(Slot))          | Tool sits in Slot of the rack               |
  | slot_free(Slot)                        | no tool in Slot                             |
  | tool_condition(Tool, ok)               | Tool may be used                            |
  | couplant_applied(goal_point(meas(Id))) | couplant film on measurement Id's spot      |
  | scanned(Tool, Arm, meas(Id))           | an SLRA range image of Id exists            |
  | measured(Tool, Arm, meas(Id))          | measurement Id is done                      |
  | calibrated(Tool)                       | Tool checked on the calibration block       |
  | couplant_refilled(couplant_station)    | the couplant reservoir has been refilled    |

Poses are `approach_point(Place)` (free space above a place), `in_contact_point(meas(Id))`
(ultrasonic probe on the part) and `viewing_pose(meas(Id))` (SLRA stand-off).  Places are
`meas(Id)`, `rack(Slot)`, `couplant_station`, `cal_block` and `home`.  The Geometric
Reasoner turns these qualitative poses into numbers.

Static facts of the cell (types, weights, payloads, rack slots) come from the world
model, kb/world.pl, through domain_fact/1.
*/

:- use_module(library(error)).
:- use_module(library(lists)).
:- use_module(world, []).
:- use_module(tools, []).


                 /*******************************
                 *        STATIC OPERATORS      *
                 *******************************/

%!  static_operator(?NameAndFormat, ?Description:list) is nondet.
%
%   NameAndFormat is an operator of the inspection domain and Description the list of
%   its Figure 3 fields: preconditions/1, adders/1, unary_constraints/1,
%   n_ary_constraints/1, resources/1, message_pattern/1, command_stream/1,
%   reply_pattern/1 and result_pattern/1, in that order.  Variables are shared across
%   the fields of one clause.

% Moving in free space between the approach points of two places.
static_operator(move(Arm, From, To),
    [ preconditions([ at(Arm, approach_point(From)) ]),
      adders([ at(Arm, approach_point(To)) ]),
      unary_constraints([ type(Arm, arm) ]),
      n_ary_constraints([]),
      resources([ Arm ]),
      message_pattern('MOVE'(approach_point(From), approach_point(To))),
      command_stream(command_stream(path_planner, Arm)),
      reply_pattern('DONE'),
      result_pattern(moved(Arm, approach_point(To)))
    ]).

% Retracting the probe from the part to the measurement's approach point.
static_operator(move_retract(Arm, Id),
    [ preconditions([ at(Arm, in_contact_point(meas(Id))) ]),
      adders([ at(Arm, approach_point(meas(Id))) ]),
      unary_constraints([ type(Arm, arm) ]),
      n_ary_constraints([]),
      resources([ Arm ]),
      message_pattern('RETRACT'(in_contact_point(meas(Id)), approach_point(meas(Id)))),
      command_stream(command_stream(path_planner, Arm)),
      reply_pattern('DONE'),
      result_pattern(moved(Arm, approach_point(meas(Id))))
    ]).

% Guarded move from the approach point until the probe touches the part.
static_operator(move_contact(Arm, Id),
    [ preconditions([ at(Arm, approach_point(meas(Id))) ]),
      adders([ at(Arm, in_contact_point(meas(Id))) ]),
      unary_constraints([ type(Arm, arm) ]),
      n_ary_constraints([]),
      resources([ Arm ]),
      message_pattern('CONTACT'(approach_point(meas(Id)), in_contact_point(meas(Id)))),
      command_stream(command_stream(path_planner, Arm)),
      reply_pattern('CONTACT'(Force)),
      result_pattern(contact(Arm, meas(Id), Force))
    ]).

% Dispensing couplant on the measurement spot from the approach point.
static_operator(apply_couplant(Arm, Id),
    [ preconditions([ at(Arm, approach_point(meas(Id))) ]),
      adders([ couplant_applied(goal_point(meas(Id))) ]),
      unary_constraints([ type(Arm, arm) ]),
      n_ary_constraints([]),
      resources([ Arm ]),
      message_pattern('COUPLANT'(goal_point(meas(Id)))),
      command_stream(command_stream(path_planner, Arm)),
      reply_pattern('DONE'),
      result_pattern(couplant_applied(meas(Id)))
    ]).

% Ultrasonic thickness measurement (Figure 3).
static_operator(us_measure(Tool, Arm, Id),
    [ preconditions([ couplant_applied(goal_point(meas(Id))),
                      at(Arm, in_contact_point(meas(Id))),
                      holding(Arm, Tool) ]),
      adders([ measured(Tool, Arm, meas(Id)) ]),
      unary_constraints([ type(Arm, arm),
                          type(Tool, us_tool) ]),
      n_ary_constraints([ can_lift(Arm, W1),
                          weight(Tool, W2),
                          W2 =< W1 ]),
      resources([ Tool, Arm ]),
      message_pattern('MEASURE'(min_value(meas(Id)), max_value(meas(Id)))),
      command_stream(command_stream(path_planner, Arm)),
      reply_pattern('VALUE'(Val)),
      result_pattern(dimension(Id, Tool, Val, 0.0))
    ]).

% Moving from a measurement's approach point to its SLRA viewing pose.
static_operator(move_view(Arm, Id),
    [ preconditions([ at(Arm, approach_point(meas(Id))) ]),
      adders([ at(Arm, viewing_pose(meas(Id))) ]),
      unary_constraints([ type(Arm, arm) ]),
      n_ary_constraints([]),
      resources([ Arm ]),
      message_pattern('MOVE'(approach_point(meas(Id)), viewing_pose(meas(Id)))),
      command_stream(command_stream(path_planner, Arm)),
      reply_pattern('DONE'),
      result_pattern(moved(Arm, viewing_pose(meas(Id))))
    ]).

% Leaving an SLRA viewing pose for the measurement's approach point.
static_operator(leave_view(Arm, Id),
    [ preconditions([ at(Arm, viewing_pose(meas(Id))) ]),
      adders([ at(Arm, approach_point(meas(Id))) ]),
      unary_constraints([ type(Arm, arm) ]),
      n_ary_constraints([]),
      resources([ Arm ]),
      message_pattern('MOVE'(viewing_pose(meas(Id)), approach_point(meas(Id)))),
      command_stream(command_stream(path_planner, Arm)),
      reply_pattern('DONE'),
      result_pattern(moved(Arm, approach_point(meas(Id))))
    ]).

% Taking an SLRA range image of a measurement's patches.
static_operator(slra_scan(Tool, Arm, Id),
    [ preconditions([ at(Arm, viewing_pose(meas(Id))),
                      holding(Arm, Tool) ]),
      adders([ scanned(Tool, Arm, meas(Id)) ]),
      unary_constraints([ type(Arm, arm),
                          type(Tool, slra_tool) ]),
      n_ary_constraints([ can_lift(Arm, W1),
                          weight(Tool, W2),
                          W2 =< W1 ]),
      resources([ Tool, Arm ]),
      message_pattern('SCAN'(patches(meas(Id)))),
      command_stream(command_stream(vision, Tool)),
      reply_pattern('IMAGE'(Image)),
      result_pattern(range_image(Id, Tool, Image))
    ]).

% Measuring a dimension from an SLRA range image (vision only, the arm is free).
static_operator(slra_measure(Tool, Arm, Id),
    [ preconditions([ scanned(Tool, Arm, meas(Id)) ]),
      adders([ measured(Tool, Arm, meas(Id)) ]),
      unary_constraints([ type(Arm, arm),
                          type(Tool, slra_tool) ]),
      n_ary_constraints([]),
      resources([ vision ]),
      message_pattern('MEASURE'(min_value(meas(Id)), max_value(meas(Id)))),
      command_stream(command_stream(vision, Tool)),
      reply_pattern('VALUE'(Val, Sigma)),
      result_pattern(dimension(Id, Tool, Val, Sigma))
    ]).

% Picking a tool up from its rack slot.
static_operator(pick_up(Arm, Tool, Slot),
    [ preconditions([ location(Tool, in_rack(Slot)),
                      tool_condition(Tool, ok),
                      holding(Arm, none),
                      at(Arm, approach_point(rack(Slot))) ]),
      adders([ holding(Arm, Tool),
               slot_free(Slot) ]),
      unary_constraints([ type(Arm, arm),
                          type(Slot, slot) ]),
      n_ary_constraints([ can_lift(Arm, W1),
                          weight(Tool, W2),
                          W2 =< W1 ]),
      resources([ Tool, Arm ]),
      message_pattern('PICKUP'(Tool, rack(Slot))),
      command_stream(command_stream(path_planner, Arm)),
      reply_pattern('DONE'),
      result_pattern(tool_location(Tool, on_arm(Arm)))
    ]).

% Putting the held tool down in a free rack slot.
static_operator(put_down(Arm, Tool, Slot),
    [ preconditions([ holding(Arm, Tool),
                      slot_free(Slot),
                      at(Arm, approach_point(rack(Slot))) ]),
      adders([ location(Tool, in_rack(Slot)),
               holding(Arm, none) ]),
      unary_constraints([ type(Arm, arm),
                          type(Slot, slot) ]),
      n_ary_constraints([ Tool \== none ]),
      resources([ Tool, Arm ]),
      message_pattern('PUTDOWN'(Tool, rack(Slot))),
      command_stream(command_stream(path_planner, Arm)),
      reply_pattern('DONE'),
      result_pattern(tool_location(Tool, in_rack(Slot)))
    ]).

% Checking an ultrasonic probe on the calibration block.
static_operator(us_check_calibration(Tool, Arm),
    [ preconditions([ holding(Arm, Tool),
                      at(Arm, approach_point(cal_block)) ]),
      adders([ calibrated(Tool) ]),
      unary_constraints([ type(Arm, arm),
                          type(Tool, us_tool) ]),
      n_ary_constraints([]),
      resources([ Tool, Arm ]),
      message_pattern('CALIBRATE'(Tool, cal_block)),
      command_stream(command_stream(path_planner, Arm)),
      reply_pattern('VALUE'(Val)),
      result_pattern(calibration(Tool, Val))
    ]).

% Checking an SLRA on the calibration block.
static_operator(slra_check_calibration(Tool, Arm),
    [ preconditions([ holding(Arm, Tool),
                      at(Arm, approach_point(cal_block)) ]),
      adders([ calibrated(Tool) ]),
      unary_constraints([ type(Arm, arm),
                          type(Tool, slra_tool) ]),
      n_ary_constraints([]),
      resources([ Tool, Arm ]),
      message_pattern('CALIBRATE'(Tool, cal_block)),
      command_stream(command_stream(vision, Tool)),
      reply_pattern('VALUE'(Val, Sigma)),
      result_pattern(calibration(Tool, Val, Sigma))
    ]).

% Refilling the couplant reservoir at the couplant station.
static_operator(refill_couplant(Arm),
    [ preconditions([ at(Arm, approach_point(couplant_station)) ]),
      adders([ couplant_refilled(couplant_station) ]),
      unary_constraints([ type(Arm, arm) ]),
      n_ary_constraints([]),
      resources([ Arm, couplant_station ]),
      message_pattern('REFILL'(couplant_station)),
      command_stream(command_stream(path_planner, Arm)),
      reply_pattern('LEVEL'(Percent)),
      result_pattern(couplant_level(Percent))
    ]).


% --- the Exception Handler's tests and repairs (kb/faults.pl names them) ---------------

% Reading the couplant station's level (a float gauge on the reservoir).
static_operator(check_couplant(Arm),
    [ preconditions([ at(Arm, approach_point(couplant_station)) ]),
      adders([ couplant_checked(couplant_station) ]),
      unary_constraints([ type(Arm, arm) ]),
      n_ary_constraints([]),
      resources([ Arm, couplant_station ]),
      message_pattern('LEVEL'(couplant_station)),
      command_stream(command_stream(path_planner, Arm)),
      reply_pattern('LEVEL'(Percent)),
      result_pattern(couplant_level(Percent))
    ]).

% Re-homing the arm and querying the robot controller.
static_operator(query_controller(Arm),
    [ preconditions([]),
      adders([ controller_checked(Arm) ]),
      unary_constraints([ type(Arm, arm) ]),
      n_ary_constraints([]),
      resources([ Arm ]),
      message_pattern('QUERY'(controller)),
      command_stream(command_stream(path_planner, Arm)),
      reply_pattern('READY'),
      result_pattern(controller_ready(Arm))
    ]).

% Resetting (power-cycling) the robot controller.
static_operator(reset_controller(Arm),
    [ preconditions([]),
      adders([ controller_reset(Arm) ]),
      unary_constraints([ type(Arm, arm) ]),
      n_ary_constraints([]),
      resources([ Arm ]),
      message_pattern('RESET'(controller)),
      command_stream(command_stream(path_planner, Arm)),
      reply_pattern('DONE'),
      result_pattern(controller_reset(Arm))
    ]).

% Purging the dispenser of the probe in hand at the couplant station.
static_operator(purge_dispenser(Tool, Arm),
    [ preconditions([ holding(Arm, Tool),
                      at(Arm, approach_point(couplant_station)) ]),
      adders([ dispenser_purged(Tool) ]),
      unary_constraints([ type(Arm, arm),
                          type(Tool, us_tool) ]),
      n_ary_constraints([]),
      resources([ Tool, Arm, couplant_station ]),
      message_pattern('PURGE'(Tool)),
      command_stream(command_stream(path_planner, Arm)),
      reply_pattern('DONE'),
      result_pattern(dispenser_purged(Tool))
    ]).

% Cleaning the window of the SLRA in hand at the couplant station's wiper.
static_operator(clean_window(Tool, Arm),
    [ preconditions([ holding(Arm, Tool),
                      at(Arm, approach_point(couplant_station)) ]),
      adders([ window_clean(Tool) ]),
      unary_constraints([ type(Arm, arm),
                          type(Tool, slra_tool) ]),
      n_ary_constraints([]),
      resources([ Tool, Arm, couplant_station ]),
      message_pattern('CLEAN'(Tool)),
      command_stream(command_stream(path_planner, Arm)),
      reply_pattern('DONE'),
      result_pattern(window_clean(Tool))
    ]).

% Reseating a sensor's cable (the cell's supervisor, between measurements).
static_operator(reseat_cable(Arm, Device),
    [ preconditions([]),
      adders([ cable_reseated(Device) ]),
      unary_constraints([ type(Arm, arm) ]),
      n_ary_constraints([]),
      resources([ Arm, Device ]),
      message_pattern('RESEAT'(Device)),
      command_stream(command_stream(path_planner, Arm)),
      reply_pattern('DONE'),
      result_pattern(cable_reseated(Device))
    ]).

% Re-calibrating the arm on the calibration block.
static_operator(recalibrate_arm(Arm),
    [ preconditions([ at(Arm, approach_point(cal_block)),
                      holding(Arm, none) ]),
      adders([ arm_calibrated(Arm) ]),
      unary_constraints([ type(Arm, arm) ]),
      n_ary_constraints([]),
      resources([ Arm ]),
      message_pattern('RECALIBRATE'(cal_block)),
      command_stream(command_stream(path_planner, Arm)),
      reply_pattern('DONE'),
      result_pattern(arm_calibrated(Arm))
    ]).

% Re-scanning a measurement's feature from a second stand-off.
static_operator(rescan(Tool, Arm, Id),
    [ preconditions([ at(Arm, viewing_pose(meas(Id))),
                      holding(Arm, Tool) ]),
      adders([ rescanned(Tool, meas(Id)) ]),
      unary_constraints([ type(Arm, arm),
                          type(Tool, slra_tool) ]),
      n_ary_constraints([]),
      resources([ Tool, Arm ]),
      message_pattern('RESCAN'(patches(meas(Id)))),
      command_stream(command_stream(vision, Tool)),
      reply_pattern('VALUE'(Val, Sigma)),
      result_pattern(dimension(Id, Tool, Val, Sigma))
    ]).


% --- a person called to the cell (the Exception Handler's recoveries the cell cannot make) -
%
% A person is a device of their own (ita/devices/person.py): a job is a message
% 'CALL'(Job) on the person's stream, answered when it is done; the run waits.

% Taking every obstacle the cell does not know out of it.
static_operator(remove_obstacles(Person),
    [ preconditions([]),
      adders([ obstacles_removed(cell) ]),
      unary_constraints([ type(Person, person) ]),
      n_ary_constraints([]),
      resources([ Person ]),
      message_pattern('CALL'(remove_obstacles)),
      command_stream(command_stream(person, Person)),
      reply_pattern('DONE'),
      result_pattern(obstacles_removed(cell))
    ]).

% Re-clamping the part on its fixture.
static_operator(reclamp_part(Person),
    [ preconditions([]),
      adders([ part_clamped(part) ]),
      unary_constraints([ type(Person, person) ]),
      n_ary_constraints([]),
      resources([ Person ]),
      message_pattern('CALL'(reclamp_part)),
      command_stream(command_stream(person, Person)),
      reply_pattern('DONE'),
      result_pattern(part_clamped(part))
    ]).

% Replacing a tool by a new one of the same kind from the stores (same name, same slot).
static_operator(replace_tool(Person, Tool),
    [ preconditions([]),
      adders([ tool_replaced(Tool) ]),
      unary_constraints([ type(Person, person) ]),
      n_ary_constraints([]),
      resources([ Person, Tool ]),
      message_pattern('CALL'(replace_tool(Tool))),
      command_stream(command_stream(person, Person)),
      reply_pattern('DONE'),
      result_pattern(tool_replaced(Tool))
    ]).

% Straightening an ultrasonic probe that sits crooked in its holder.
static_operator(straighten_probe(Person, Tool),
    [ preconditions([]),
      adders([ probe_straightened(Tool) ]),
      unary_constraints([ type(Person, person),
                          type(Tool, us_tool) ]),
      n_ary_constraints([]),
      resources([ Person, Tool ]),
      message_pattern('CALL'(straighten_probe(Tool))),
      command_stream(command_stream(person, Person)),
      reply_pattern('DONE'),
      result_pattern(probe_straightened(Tool))
    ]).


                 /*******************************
                 *      DEDUCTIVE OPERATORS     *
                 *******************************/

%!  deductive_operator(?NameAndFormat, ?Description:list) is nondet.
%
%   When a step adds a fact unifying with NameAndFormat, the propositions of
%   Description's `denied(List)` no longer hold.  `neq(X)` in a denied proposition
%   matches any value other than X.

% Figure 3: picking up a tool takes it out of the rack and out of any other hand.
deductive_operator(holding(Arm, Tool),
    [ denied([ location(Tool, in_rack(_Slot)),
               holding(Arm, neq(Tool)) ]) ]).

% An arm is at one pose at a time.
deductive_operator(at(Arm, Pose),
    [ denied([ at(Arm, neq(Pose)) ]) ]).

% A tool put in a slot fills it.
deductive_operator(location(_Tool, in_rack(Slot)),
    [ denied([ slot_free(Slot) ]) ]).

% An ultrasonic measurement uses up the couplant film on its spot.
deductive_operator(measured(_Tool, _Arm, meas(Id)),
    [ denied([ couplant_applied(goal_point(meas(Id))) ]) ]).


                 /*******************************
                 *   CRITICALITIES AND FIELDS   *
                 *******************************/

%!  operator_field(?NameAndFormat, ?Field, ?Value) is nondet.
%
%   Value is the Field (e.g. `preconditions`, `message_pattern`) of the static operator
%   NameAndFormat.

operator_field(NameAndFormat, Field, Value) :-
    static_operator(NameAndFormat, Description),
    member(Entry, Description),
    Entry =.. [Field, Value].

%!  criticality(?Goal, ?Weight) is nondet.
%
%   ABSTRIPS criticality of goals and preconditions unifying with Goal: the planner
%   works on the unsatisfied goals of the highest Weight first.  Facts that take the
%   longest detours (a tool in hand) weigh most; poses, cheapest to change, least.

criticality(tool_condition(_, _), 6).
criticality(measured(_, _, _), 5).
criticality(calibrated(_), 5).
criticality(couplant_refilled(_), 5).
criticality(couplant_checked(_), 5).
criticality(controller_checked(_), 5).
criticality(controller_reset(_), 5).
criticality(dispenser_purged(_), 5).
criticality(window_clean(_), 5).
criticality(cable_reseated(_), 5).
criticality(arm_calibrated(_), 5).
criticality(rescanned(_, _), 5).
criticality(obstacles_removed(_), 5).
criticality(part_clamped(_), 5).
criticality(tool_replaced(_), 5).
criticality(probe_straightened(_), 5).
criticality(location(_, _), 4).
criticality(slot_free(_), 4).
criticality(holding(_, _), 3).
criticality(scanned(_, _, _), 2).
criticality(couplant_applied(_), 2).
criticality(at(_, _), 1).


                 /*******************************
                 *          DOMAIN FACTS        *
                 *******************************/

%!  domain_fact(?Fact) is nondet.
%
%   Fact is a static fact of the workcell that unary and n-ary constraints are checked
%   against: type/2 (an object's type or one it is a kind of, world:is_a/2, so the bent
%   probe passes an operator's `type(Tool, us_tool)`; and `type(Person, person)` for the
%   people the cell can call, person/1), weight/2 and can_lift/2 of the world model
%   (kb/world.pl), and
%   can_measure(Tool, Kind), a tool whose type some tool rule of kb/tools.pl lets
%   measure Kind.

domain_fact(type(Object, Type)) :-
    world:is_a(Object, Type).
domain_fact(type(Person, person)) :-
    person(Person).
domain_fact(weight(Tool, Kg)) :-
    world:weight(Tool, Kg).
domain_fact(can_lift(Arm, Kg)) :-
    world:can_lift(Arm, Kg).
domain_fact(can_measure(Tool, Kind)) :-
    world:tool(Tool),
    world:type(Tool, ToolType),
    tools:tool_type_measures(ToolType, Kind).

%!  person(?Person) is nondet.
%
%   Person can be called to the cell (the run waits for them): the device of the stream
%   `command_stream(person, Person)`.

person(technician).

%!  measurement_goal(+Id, +Kind, ?Tool, -Goal, -Constraints:list) is det.
%
%   Goal is the planning goal `measured(Tool, Arm, meas(Id))` for measurement Id of
%   Kind, and Constraints the goal constraints on its variables: Arm an arm, Tool a tool
%   that can take measurements of Kind (can_measure/2 of domain_fact/1, from the tool
%   rules of kb/tools.pl).  Tool is the Sequence Planner's choice, bound, when the
%   Operation Planner plans a measurement of the run; unbound, the planner chooses.
%
%   @error domain_error(measurement_kind, Kind) for an unknown kind
%   @error existence_error(tool, Tool) for a bound Tool that is not a tool
%   @error domain_error(tool_for(Kind), Tool) for a tool whose type cannot measure Kind

measurement_goal(Id, Kind, Tool, measured(Tool, Arm, meas(Id)), [can_measure(Tool, Kind), type(Arm, arm)]) :-
    must_be(atomic, Id),
    must_be(atom, Kind),
    (   tools:measurement_kind(Kind)
    ->  true
    ;   domain_error(measurement_kind, Kind)
    ),
    (   var(Tool)
    ->  true
    ;   \+ world:tool(Tool)
    ->  must_be(atom, Tool),
        existence_error(tool, Tool)
    ;   domain_fact(can_measure(Tool, Kind))
    ->  true
    ;   domain_error(tool_for(Kind), Tool)
    ).

%!  world_state(+Arm, +Pose, -State:list) is det.
%
%   State is the planning state of the world model now, with Arm at Pose: what each
%   tool's location and condition is, which slots are free, what Arm holds.

world_state(Arm, Pose, State) :-
    must_be(atom, Arm),
    must_be(ground, Pose),
    findall(Fact, world_fact(Arm, Fact), Facts),
    sort([at(Arm, Pose)|Facts], State).

%!  planning_state(+Arm, +Pose, +Holding, -State:list) is det.
%
%   State is the planning state with Arm at Pose holding Holding (a tool, or `none`):
%   the other tools where the world model has them, their conditions, the free slots.
%   A held tool is out of the rack whatever the world model says, so its slot is free.
%   This is the state the Operation Planner's facade plans from; the executive keeps
%   Arm, Pose and Holding between measurements and the world model the rest.
%
%   @error existence_error(tool, Holding) if Holding is neither a tool nor `none`

planning_state(Arm, Pose, Holding, State) :-
    must_be_planning_state(Arm, Pose, Holding),
    findall(Fact, held_state_fact(Holding, Fact), Facts),
    sort([at(Arm, Pose), holding(Arm, Holding)|Facts], State).

%!  must_be_planning_state(+Arm, +Pose, +Holding) is det.
%
%   Arm, Pose and Holding describe a planning state (planning_state/4).
%
%   @error existence_error(tool, Holding) if Holding is neither a tool nor `none`
%   @error type_error(...) or instantiation_error(...) for a non-atom Arm or Holding or
%   a non-ground Pose

must_be_planning_state(Arm, Pose, Holding) :-
    (   atom(Arm),
        atom(Holding),
        ground(Pose)
    ->  true
    ;   must_be(atom, Arm),
        must_be(ground, Pose),
        must_be(atom, Holding)
    ),
    (   ( Holding == none ; world:tool(Holding) )
    ->  true
    ;   existence_error(tool, Holding)
    ).

%!  planning_state_facts(+Holding, ?Pattern, -Facts:list) is det.
%
%   Facts are the facts of the planning state of an arm holding Holding
%   (planning_state/4) that unify with Pattern, in the order of that state (the
%   standard order of terms), leaving out the arm's own at/2 and holding/2 facts, which
%   the caller knows.  MACROP lookup asks for the few facts a MACROP's preconditions
%   mention instead of deriving the whole state.

planning_state_facts(Holding, Pattern, Facts) :-
    findall(Pattern, held_state_fact(Holding, Pattern), Facts0),
    sort(Facts0, Facts).

held_state_fact(Holding, location(Tool, in_rack(Slot))) :-
    world:location(Tool, in_rack(Slot)),
    Tool \== Holding.
held_state_fact(_, tool_condition(Tool, Condition)) :-
    world:tool_condition(Tool, Condition).
held_state_fact(Holding, slot_free(Slot)) :-
    world:rack_slot(_, Slot),
    \+ ( world:location(Tool, in_rack(Slot)), Tool \== Holding ).

world_fact(_, location(Tool, in_rack(Slot))) :-
    world:location(Tool, in_rack(Slot)).
world_fact(_, tool_condition(Tool, Condition)) :-
    world:tool_condition(Tool, Condition).
world_fact(_, slot_free(Slot)) :-
    world:rack_slot(_, Slot),
    \+ world:location(_, in_rack(Slot)).
world_fact(Arm, holding(Arm, Tool)) :-
    (   world:holding(Arm, Tool0)
    ->  Tool = Tool0
    ;   Tool = none
    ).
