:- module(world,
          [ type/2,                     % ?Object, ?Type
            subtype/2,                  % ?Type, ?SuperType
            is_a/2,                     % ?Object, ?Type
            tool/1,                     % ?Tool
            weight/2,                   % ?Tool, ?Kg
            can_lift/2,                 % ?Arm, ?Kg
            spare_of/2,                 % ?Spare, ?Tool
            home_slot/2,                % ?Tool, ?Slot
            rack_slot/2,                % ?Rack, ?Slot
            location/2,                 % ?Tool, ?Where
            tool_condition/2,           % ?Tool, ?Condition
            couplant_level/1,           % -Percent
            couplant_low/0,
            missing/1,                  % ?Tool
            available/1,                % ?Tool
            holding/2,                  % ?Arm, ?Tool
            liftable/2,                 % ?Arm, ?Tool
            usable/3,                   % ?Arm, ?ToolType, ?Tool
            replacement/2,              % ?Tool, ?Spare
            set_tool_condition/2,       % +Tool, +Condition
            set_location/2,             % +Tool, +Where
            set_couplant_level/1,       % +Percent
            reserved/2,                 % ?Tool, ?Arm
            set_reserved/2,             % +Tool, +Arm
            reset_world/0
          ]).

/** <module> World model of the default ITA workcell

Symbolic facts about the workcell that tool selection, the task planner and fault
diagnosis reason with: one T3 arm, two ultrasonic probes and two scanning laser range
assemblies (SLRA), each pair a tool and its spare, and an ultrasonic probe bent 90
degrees (no spare) in a five-slot tool rack, a couplant station and a calibration block.

The static facts describe the cell as built.  The world *state* (where each tool is,
its condition, the couplant level) is the built state changed by the updates recorded
with set_location/2, set_tool_condition/2 and set_couplant_level/1; reset_world/0
forgets the updates.  Nothing runs at load time.
*/

:- use_module(library(error)).

:- dynamic moved/2.                     % moved(Tool, Where): location update
:- dynamic condition_update/2.          % condition_update(Tool, Condition)
:- dynamic couplant_update/1.           % couplant_update(Percent)
:- dynamic reserved/2.                  % reserved(Tool, Arm): kept for another arm


                 /*******************************
                 *        THE CELL AS BUILT     *
                 *******************************/

%!  type(?Object, ?Type) is nondet.
%
%   Object of the workcell is of Type: `arm`, `us_tool` (ultrasonic thickness probe),
%   `us_bent` (ultrasonic thickness probe bent 90 degrees, for walls the other cannot
%   touch), `slra_tool` (scanning laser range assembly), `rack`, `slot`,
%   `couplant_station` or `calibration_block`.  Each object has one type; is_a/2 adds
%   the types it is a kind of.

type(t3, arm).
type(us_probe_1, us_tool).
type(us_probe_2, us_tool).
type(us_probe_90, us_bent).
type(slra_1, slra_tool).
type(slra_2, slra_tool).
type(rack, rack).
type(slot_1, slot).
type(slot_2, slot).
type(slot_3, slot).
type(slot_4, slot).
type(slot_5, slot).
type(couplant_station, couplant_station).
type(cal_block, calibration_block).

%!  subtype(?Type, ?SuperType) is nondet.
%
%   Every object of Type is also one of SuperType: the bent probe is an ultrasonic
%   probe (it works the same gauge, couplant and calibration block), though tool
%   selection keeps the two apart (the rules of kb/tools.pl name the exact type).

subtype(us_bent, us_tool).

%!  is_a(?Object, ?Type) is nondet.
%
%   Object is of Type or of a subtype of it (subtype/2): what an operator's
%   `type(Tool, us_tool)` constraint asks of a tool.

is_a(Object, Type) :-
    type(Object, Own),
    (   Type = Own
    ;   subtype(Own, Type)
    ).

%!  tool(?Tool) is nondet.
%
%   Tool is a measuring tool the arm can pick up (of type `us_tool`, `us_bent` or
%   `slra_tool`).

tool(Tool) :-
    type(Tool, Type),
    tool_type(Type).

tool_type(us_tool).
tool_type(us_bent).
tool_type(slra_tool).

%!  weight(?Tool, ?Kg) is nondet.
%
%   Tool weighs Kg kilograms, tool changer adapter included.

weight(us_probe_1, 1.5).
weight(us_probe_2, 1.5).
weight(us_probe_90, 1.6).
weight(slra_1, 6.0).
weight(slra_2, 6.0).

%!  can_lift(?Arm, ?Kg) is nondet.
%
%   Arm has a rated payload of Kg kilograms.

can_lift(t3, 45).

%!  spare_of(?Spare, ?Tool) is nondet.
%
%   Spare is the spare that replaces Tool when Tool is broken, worn or missing.

spare_of(us_probe_2, us_probe_1).
spare_of(slra_2, slra_1).

%!  home_slot(?Tool, ?Slot) is nondet.
%
%   Tool is kept in Slot of the rack when the arm does not hold it.

home_slot(us_probe_1, slot_1).
home_slot(us_probe_2, slot_2).
home_slot(slra_1, slot_3).
home_slot(slra_2, slot_4).
home_slot(us_probe_90, slot_5).

%!  rack_slot(?Rack, ?Slot) is nondet.
%
%   Slot is one of the tool slots of Rack.

rack_slot(rack, slot_1).
rack_slot(rack, slot_2).
rack_slot(rack, slot_3).
rack_slot(rack, slot_4).
rack_slot(rack, slot_5).


                 /*******************************
                 *          WORLD STATE         *
                 *******************************/

%!  location(?Tool, ?Where) is nondet.
%
%   Tool is at Where: `in_rack(Slot)`, `on_arm(Arm)` or `missing`.  A tool is in its
%   home slot unless set_location/2 moved it.

location(Tool, Where) :-
    tool(Tool),
    (   moved(Tool, Where0)
    ->  Where = Where0
    ;   home_slot(Tool, Slot),
        Where = in_rack(Slot)
    ).

%!  tool_condition(?Tool, ?Condition) is nondet.
%
%   Tool is in Condition: `ok`, `worn` or `broken`.  Tools are `ok` unless
%   set_tool_condition/2 said otherwise.

tool_condition(Tool, Condition) :-
    tool(Tool),
    (   condition_update(Tool, Condition0)
    ->  Condition = Condition0
    ;   Condition = ok
    ).

%!  couplant_level(-Percent) is det.
%
%   The couplant reservoir is Percent full (100 unless set_couplant_level/1 changed it).

couplant_level(Percent) :-
    (   couplant_update(Percent0)
    ->  Percent = Percent0
    ;   Percent = 100
    ).

%!  couplant_low is semidet.
%
%   True when the couplant reservoir is below 20 % and must be refilled before an
%   ultrasonic measurement.

couplant_low :-
    couplant_level(Percent),
    Percent < 20.

%!  missing(?Tool) is nondet.
%
%   Tool is not where it should be: its location is `missing`.

missing(Tool) :-
    location(Tool, missing).

%!  available(?Tool) is nondet.
%
%   Tool can be used: its condition is `ok` and it is not missing.

available(Tool) :-
    tool_condition(Tool, ok),
    \+ missing(Tool),
    \+ reserved(Tool, _).

%!  reserved(?Tool, ?Arm) is nondet.
%
%   Tool is kept for Arm, the other arm of a two-arm run (each arm its own tools): it
%   stays in its slot, and this arm does not use it (not available/1).

%!  holding(?Arm, ?Tool) is nondet.
%
%   Arm holds Tool.

holding(Arm, Tool) :-
    type(Arm, arm),
    location(Tool, on_arm(Arm)).

%!  liftable(?Arm, ?Tool) is nondet.
%
%   Tool weighs no more than the payload of Arm (the n-ary constraint of the seed's
%   operators: `can_lift(Arm, W1), weight(Tool, W2), W2 =< W1`).

liftable(Arm, Tool) :-
    can_lift(Arm, Payload),
    weight(Tool, Weight),
    Weight =< Payload.

%!  usable(?Arm, ?ToolType, ?Tool) is nondet.
%
%   Arm can measure with Tool of ToolType now: Arm is an arm, Tool has the type, is
%   available, and Arm can lift it.

usable(Arm, ToolType, Tool) :-
    type(Arm, arm),
    type(Tool, ToolType),
    tool_type(ToolType),
    available(Tool),
    liftable(Arm, Tool).

%!  replacement(?Tool, ?Spare) is nondet.
%
%   Spare is an available spare for Tool.

replacement(Tool, Spare) :-
    spare_of(Spare, Tool),
    available(Spare).


                 /*******************************
                 *            UPDATES           *
                 *******************************/

%!  set_tool_condition(+Tool, +Condition) is det.
%
%   Record that Tool is now in Condition (`ok`, `worn` or `broken`).
%
%   @error domain_error(tool, Tool) if Tool is not a tool of the cell
%   @error domain_error(tool_condition, Condition) for an unknown condition

set_tool_condition(Tool, Condition) :-
    must_be_tool(Tool),
    must_be(atom, Condition),
    (   memberchk(Condition, [ok, worn, broken])
    ->  true
    ;   domain_error(tool_condition, Condition)
    ),
    retractall(condition_update(Tool, _)),
    assertz(condition_update(Tool, Condition)).

%!  set_location(+Tool, +Where) is det.
%
%   Record that Tool is now at Where: `in_rack(Slot)`, `on_arm(Arm)` or `missing`.
%
%   @error domain_error(tool, Tool) if Tool is not a tool of the cell
%   @error domain_error(tool_location, Where) for a place that is not one of those

set_location(Tool, Where) :-
    must_be_tool(Tool),
    must_be(nonvar, Where),
    (   valid_location(Where)
    ->  true
    ;   domain_error(tool_location, Where)
    ),
    retractall(moved(Tool, _)),
    assertz(moved(Tool, Where)).

valid_location(in_rack(Slot)) :- atom(Slot), rack_slot(_, Slot).
valid_location(on_arm(Arm)) :- atom(Arm), type(Arm, arm).
valid_location(missing).

%!  set_reserved(+Tool, +Arm) is det.
%
%   Record that Tool is kept for Arm (another arm) from now on: see reserved/2.
%
%   @error domain_error(tool, Tool) if Tool is not a tool of the cell

set_reserved(Tool, Arm) :-
    must_be_tool(Tool),
    must_be(atom, Arm),
    retractall(reserved(Tool, _)),
    assertz(reserved(Tool, Arm)).

%!  set_couplant_level(+Percent) is det.
%
%   Record that the couplant reservoir is now Percent full.
%
%   @error type_error(number, Percent) if Percent is not a number
%   @error domain_error(percent, Percent) outside 0..100

set_couplant_level(Percent) :-
    must_be(number, Percent),
    (   between_0_100(Percent)
    ->  true
    ;   domain_error(percent, Percent)
    ),
    retractall(couplant_update(_)),
    assertz(couplant_update(Percent)).

between_0_100(X) :- X >= 0, X =< 100.

%!  reset_world is det.
%
%   Forget every update: all tools in their home slots and `ok`, couplant full.

reset_world :-
    retractall(moved(_, _)),
    retractall(condition_update(_, _)),
    retractall(couplant_update(_)),
    retractall(reserved(_, _)).

must_be_tool(Tool) :-
    must_be(atom, Tool),
    (   tool(Tool)
    ->  true
    ;   domain_error(tool, Tool)
    ).
