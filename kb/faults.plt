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

test(the_cal_block_tells_a_worn_probe, true(O == doubled)) :-
    test_outcome(read_cal_block, worn_probe(us_probe_2), [probe=us_probe_2], O).

test(a_test_verifies_what_it_does_not_list, true(O == ok)) :-
    test_outcome(read_cal_block, out_of_tolerance, [], O).

test(outcomes_of_the_couplant_check, true(Os == [ok, bump, empty, silent])) :-
    findall(O, outcome(check_couplant_station, O), Os).

test(a_broken_probe_is_marked, true(A == [mark(us_probe_1, broken), replace_if_no_spare(us_probe_1)])) :-
    recovery(broken_probe(us_probe_1), A).

test(repair_unless_a_new_plan_is_shorter, true(Ws == [repair, repair, replan, replan, repair, none])) :-
    findall(W, ( member(R-P, [steps(4)-steps(4), steps(3)-steps(5), steps(6)-steps(4), none-steps(4),
                              steps(2)-none, none-none]),
                 recovery_way(R, P, W) ), Ws).

test(unknown_exception, error(existence_error(exception, smoke))) :-
    candidate_causes(smoke, [], _).

:- end_tests(faults).
