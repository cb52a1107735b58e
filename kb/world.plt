:- begin_tests(world, [setup(reset_world), cleanup(reset_world)]).

:- use_module(world).

test(arm_type, true(Arm == t3)) :-
    type(Arm, arm).

test(us_tools, all(T == [us_probe_1, us_probe_2])) :-
    type(T, us_tool).

test(tools_start_in_their_home_slots, true(Where == in_rack(slot_3))) :-
    location(slra_1, Where).

test(spare, true(Spare == slra_2)) :-
    spare_of(Spare, slra_1).

test(bent_probe_is_an_ultrasonic_probe_of_its_own_type,
     all(T == [us_probe_1, us_probe_2, us_probe_90])) :-
    is_a(T, us_tool).

test(bent_probe_has_its_own_type_and_slot, true(Type-Slot == us_bent-slot_5)) :-
    type(us_probe_90, Type),
    home_slot(us_probe_90, Slot).

test(bent_probe_is_no_spare_of_the_straight_one, fail) :-
    spare_of(us_probe_90, _).

test(all_tools_available_initially, all(T == [us_probe_1, us_probe_2, us_probe_90, slra_1, slra_2])) :-
    available(T).

test(broken_tool_is_not_available,
     [ setup(set_tool_condition(us_probe_1, broken)), cleanup(reset_world), fail ]) :-
    available(us_probe_1).

test(replacement_for_broken_tool,
     [ setup(set_tool_condition(us_probe_1, broken)), cleanup(reset_world),
       true(Spare == us_probe_2) ]) :-
    \+ available(us_probe_1),
    replacement(us_probe_1, Spare).

test(missing_tool_is_not_available,
     [ setup(set_location(slra_1, missing)), cleanup(reset_world), fail ]) :-
    available(slra_1).

test(holding_after_pickup,
     [ setup(set_location(us_probe_1, on_arm(t3))), cleanup(reset_world),
       nondet, true(Tool == us_probe_1) ]) :-
    holding(t3, Tool).

test(t3_lifts_every_tool, all(T == [slra_1, slra_2, us_probe_1, us_probe_2, us_probe_90])) :-
    setof(Tool, liftable(t3, Tool), Tools),
    member(T, Tools).

test(usable_us_tool, true(Tool == us_probe_1)) :-
    once(usable(t3, us_tool, Tool)).

test(couplant_low_after_update,
     [ setup(set_couplant_level(10)), cleanup(reset_world) ]) :-
    couplant_low.

test(couplant_full_initially, fail) :-
    couplant_low.

test(reset_forgets_updates, true(C == ok)) :-
    set_tool_condition(us_probe_2, worn),
    reset_world,
    tool_condition(us_probe_2, C).

test(unknown_tool_condition, error(domain_error(tool_condition, melted))) :-
    set_tool_condition(us_probe_1, melted).

test(unknown_tool, error(domain_error(tool, hammer))) :-
    set_tool_condition(hammer, ok).

test(unknown_location, error(domain_error(tool_location, in_rack(slot_9)))) :-
    set_location(us_probe_1, in_rack(slot_9)).

test(couplant_out_of_range, error(domain_error(percent, 140))) :-
    set_couplant_level(140).

test(couplant_not_a_number, error(type_error(number, full))) :-
    set_couplant_level(full).

test(reserved_for_the_other_arm, [true(Usable-Slot == [us_probe_2]-in_rack(slot_1))]) :-
    set_reserved(us_probe_1, t3_b),
    findall(T, usable(t3, us_tool, T), Usable),
    location(us_probe_1, Slot).

test(reserved_forgotten_on_reset, [true(Usable == [us_probe_1, us_probe_2])]) :-
    set_reserved(us_probe_1, t3_b),
    reset_world,
    findall(T, usable(t3, us_tool, T), Usable).

test(reserved_unknown_tool, error(domain_error(tool, hammer))) :-
    set_reserved(hammer, t3_b).

:- end_tests(world).
