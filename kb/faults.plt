:- use_module(faults).

/*  Tests of the fault diagnosis knowledge base: every exception has causes, every cause
    a prior and a recovery, every test its needs; the diagnosis outcomes are pinned in
    prolog/diagnosis.plt.  */

:- begin_tests(faults).

test(every_exception_has_a_cause, true(Orphans == [])) :-
    findall(E, ( exception(E, _), \+ raises(_, E, _) ), Orphans).

test(every_raised_exception_is_known, true(Unknown == [])) :-
    findall(E, ( raises(_, E, _), \+ exception(E, _) ), Unknown0),
    sort(Unknown0, Unknown).

test(every_cause_has_a_prior_and_a_recovery, true(Missing == [])) :-
    findall(C, ( cause(C, _), \+ ( prior(C, _), recovery(C, _) ) ), Missing).

test(every_test_has_needs_and_a_cost, true(Missing == [])) :-
    findall(T, ( test(T, _, S), \+ ( test_needs(T, _), number(S), S > 0 ) ), Missing).

test(likelihoods_are_probabilities, true(Bad == [])) :-
    findall(C-E, ( raises(C, E, L), \+ ( L > 0, L =< 1 ) ), Bad).

test(no_echo_with_a_probe_in_hand,
     true(Causes == [broken_probe(us_probe_1), sensor_cable_fault(gauge), arm_drift, transient_glitch])) :-
    candidate_causes(no_echo, [probe=us_probe_1, device=gauge], Pairs),
    pairs_keys(Pairs, Causes).

test(a_cause_needs_its_context, true(Causes == [sensor_cable_fault(gauge), arm_drift, transient_glitch])) :-
    candidate_causes(no_echo, [device=gauge], Pairs),
    pairs_keys(Pairs, Causes).

% a view the nominal part leaves nothing to measure on is no fault: no cable, no recovery
test(a_view_with_nothing_to_measure_on_is_no_fault, true(Causes == [view_cannot_measure])) :-
    findall(C, raises(C, view_not_measurable, _), Causes).

test(the_cal_block_tells_a_worn_probe, true(O == doubled)) :-
    test_outcome(read_cal_block, worn_probe(us_probe_2), [probe=us_probe_2], O).

test(a_test_verifies_what_it_does_not_list, true(O == ok)) :-
    test_outcome(read_cal_block, out_of_tolerance, [], O).

test(outcomes_of_the_couplant_check, true(Os == [ok, bump, empty, silent])) :-
    findall(O, outcome(check_couplant_station, O), Os).

test(a_broken_probe_is_marked_and_replaced_unless_a_spare_is_left,
     true(A == [ world(tool_condition(us_probe_1, broken)),
                 unless(spare_left(us_probe_1), [ achieve(tool_replaced(us_probe_1)),
                                                  world(tool_condition(us_probe_1, ok)) ]) ])) :-
    recovery(broken_probe(us_probe_1), A).

test(which_recovery_for_which_cause,
     true(Rs =@= [ dry_couplant(us_probe_1)-[achieve(dispenser_purged(us_probe_1))],
                   empty_couplant_station-[achieve(couplant_refilled(couplant_station))],
                   controller_not_answering-[achieve(controller_reset(_))],
                   sensor_cable_fault(slra_1)-[achieve(cable_reseated(slra_1))],
                   obstacle_at_arm-[achieve(obstacles_removed(cell))],
                   part_displaced-[first_of([[register(part)], [achieve(part_clamped(part)), register(part)]]),
                                   remeasure(since_check)],
                   occlusion-[accept(test(rescan_second_standoff))],
                   out_of_tolerance-[accept(reading)],
                   tool_missing(slra_2)-[world(location(slra_2, missing))],
                   transient_glitch-[retry],
                   tilted_probe(us_probe_2)-[achieve(probe_straightened(us_probe_2))],
                   couplant_missed-[] ])) :-
    findall(C-A, ( member(C, [dry_couplant(us_probe_1), empty_couplant_station, controller_not_answering,
                              sensor_cable_fault(slra_1), obstacle_at_arm, part_displaced, occlusion,
                              out_of_tolerance, tool_missing(slra_2), transient_glitch,
                              tilted_probe(us_probe_2), couplant_missed]),
                   recovery(C, A) ), Rs).

%   the actions of a recovery, unless/2's included
recovery_action(Cause, Action) :-
    recovery(Cause, Actions),
    action_in(Actions, Action).

action_in(Actions, Action) :-
    member(A, Actions),
    (   A = unless(_, Inner)
    ->  ( Action = A ; action_in(Inner, Action) )
    ;   A = first_of(Alternatives)
    ->  ( Action = A ; member(Inner, Alternatives), action_in(Inner, Action) )
    ;   Action = A
    ).

test(every_recovery_action_is_of_a_kind_the_handler_knows, true(Bad == [])) :-
    findall(C-A, ( recovery_action(C, A),
                   \+ memberchk(A, [world(_), achieve(_), unless(_, _), first_of(_), accept(reading),
                                        accept(test(_)), retry, register(part), remeasure(since_check)]) ),
            Bad).

test(every_goal_to_achieve_is_an_operators_adder, true(Bad == [])) :-
    findall(G, ( recovery_action(_, achieve(G)), \+ recovery_goal(G) ), Bad).

test(every_accepted_test_is_a_test, true(Bad == [])) :-
    findall(T, ( recovery_action(_, accept(test(T))), \+ test(T, _, _) ), Bad).

test(every_condition_is_one_the_world_model_answers, true(Bad == [])) :-
    findall(Cond, ( recovery_action(_, unless(Cond, _)), \+ memberchk(Cond, [spare_left(_)]) ), Bad).

test(a_spare_is_left_until_both_probes_are_marked,
     [ setup(world:reset_world), cleanup(world:reset_world),
       true(Left == [true, true, false, true]) ]) :-
    Check = [L]>>( holds_now(spare_left(us_probe_1)) -> L = true ; L = false ),
    call(Check, L1),
    world_update(tool_condition(us_probe_1, broken)),
    call(Check, L2),
    world_update(tool_condition(us_probe_2, worn)),
    call(Check, L3),
    world_update(tool_condition(us_probe_2, ok)),
    call(Check, L4),
    Left = [L1, L2, L3, L4].

test(the_bent_probe_has_no_spare, [setup(world:reset_world), cleanup(world:reset_world), fail]) :-
    holds_now(spare_left(us_probe_90)).

test(a_tool_marked_missing, [setup(world:reset_world), cleanup(world:reset_world)]) :-
    world_update(location(slra_2, missing)),
    world:missing(slra_2).

test(an_unknown_world_change, error(domain_error(world_change, couplant(full)))) :-
    world_update(couplant(full)).

test(a_tilted_probe_is_told_from_drift_by_the_reference_feature,
     true(C == tilted_probe(us_probe_1))) :-
    isolated(misaligned, [probe=us_probe_1, device=gauge],
             [read_cal_block-misaligned, measure_reference_feature-ok], C).

test(the_cal_block_alone_does_not_tell_a_tilted_probe_from_drift, fail) :-
    isolated(misaligned, [probe=us_probe_1, device=gauge], [read_cal_block-misaligned], _).

test(repair_unless_a_new_plan_is_shorter, true(Ws == [repair, repair, replan, replan, repair, none])) :-
    findall(W, ( member(R-P, [steps(4)-steps(4), steps(3)-steps(5), steps(6)-steps(4), none-steps(4),
                              steps(2)-none, none-none]),
                 recovery_way(R, P, W) ), Ws).

test(unknown_exception, error(existence_error(exception, smoke))) :-
    candidate_causes(smoke, [], _).

:- end_tests(faults).
