:- use_module(diagnosis).

/*  Tests of the diagnosis engine: posteriors, interpretation, the exact tree against
    brute force, and the outcomes the fault knowledge base gives (which cause, which first
    test), pinned like the tool rules.  */

probe_ctx([probe=us_probe_1, device=gauge]).
gauge_tests([read_cal_block-20.0, check_couplant_station-15.0, retry_reading-5.0,
             query_controller-12.0]).

%   brute(+Probs, +Tests, +S, -E): the least expected cost over every decision tree
%   for the causes in S (a list of indices): the definition, by exhaustive recursion.

brute(_, _, [_], 0) :- !.
brute(Probs, Tests, S, E) :-
    findall(Cost,
            ( member(test(_, C, Os), Tests),
              findall(O-I, ( member(I, S), nth0(I, Os, O) ), Pairs),
              keysort(Pairs, Sorted),
              group_pairs_by_key(Sorted, Groups),
              Groups = [_, _|_],
              mass(Probs, S, PS),
              foldl([_-Is, A0, A1]>>( brute(Probs, Tests, Is, EI), mass(Probs, Is, PI),
                                       A1 is A0 + PI / PS * EI ),
                    Groups, 0, Below),
              Cost is C + Below ),
            Costs),
    (   Costs == [] -> E = 0 ; min_list(Costs, E) ).

mass(Probs, Is, P) :-
    foldl([I, A0, A1]>>( nth0(I, Probs, Q), A1 is A0 + Q ), Is, 0, P).

random_problem(N, T, Probs, Tests) :-
    numlist(1, N, Ns),
    maplist([_, W]>>random_between(1, 20, W), Ns, Ws),
    sum_list(Ws, Sum),
    maplist([W, P]>>(P is W / Sum), Ws, Probs),
    numlist(1, T, Ts),
    maplist([K, test(K, C, Os)]>>( random_between(1, 100, C),
                                    maplist([_, O]>>random_between(0, 2, O), Ns, Os) ),
            Ts, Tests).

:- begin_tests(diagnosis).

test(posterior_is_normalised_most_probable_first, true(First-Sum == broken_probe(us_probe_1)-1.0)) :-
    probe_ctx(C),
    posterior(no_echo, C, [], P),
    P = [First-_|_],
    pairs_values(P, Ps), sum_list(Ps, Sum0), Sum is round(Sum0 * 1e9) / 1e9.

test(learned_counts_move_the_posterior, true(First == transient_glitch)) :-
    probe_ctx(C),
    posterior(no_echo, C, [transient_glitch-40], [First-_|_]).

test(a_result_rules_causes_out, true(Kept == [broken_probe(us_probe_1)])) :-
    probe_ctx(C),
    posterior(no_echo, C, [], P),
    consistent(P, read_cal_block, no_echo, C, R),
    pairs_keys(R, Kept).

test(exact_tree_equals_brute_force, [forall(between(1, 25, Seed)), true(abs(E - B) < 1e-9)]) :-
    set_random(seed(Seed)),
    random_between(2, 6, N),
    random_between(1, 4, T),
    random_problem(N, T, Probs, Tests),
    problem_tree(Probs, Tests, optimal, _, E),
    numlist(0, N, All0), last(All0, N), exclude(==(N), All0, All),
    brute(Probs, Tests, All, B).

test(exact_is_never_worse_than_the_heuristics, [forall(between(1, 10, Seed)), true(Ok == true)]) :-
    set_random(seed(Seed)),
    random_problem(10, 10, Probs, Tests),
    problem_tree(Probs, Tests, optimal, _, E0),
    problem_tree(Probs, Tests, rollout, _, E1),
    problem_tree(Probs, Tests, greedy, _, E2),
    problem_tree(Probs, Tests, cheapest, _, E3),
    ( E0 =< E1 + 1e-9, E0 =< E2 + 1e-9, E0 =< E3 + 1e-9, E1 =< E2 + 1e-9 -> Ok = true ; Ok = false ).

test(sixteen_causes_and_tests_exactly, true(E > 0)) :-
    set_random(seed(16)),
    random_problem(16, 16, Probs, Tests),
    problem_tree(Probs, Tests, optimal, _, E).

% --- the knowledge base's outcomes, pinned ----------------------------------------

test(no_echo_first_test, true(Choice == test(read_cal_block))) :-
    probe_ctx(C), gauge_tests(T),
    step(no_echo, C, [], [], T, auto, [Choice|_]).

test(no_echo_cal_block_dead_isolates_the_probe, true(Choice == isolated(broken_probe(us_probe_1)))) :-
    probe_ctx(C), gauge_tests(T),
    step(no_echo, C, [], [read_cal_block-no_echo], T, auto, [Choice|_]).

test(no_couplant_first_test_is_the_station, true(Choice == test(check_couplant_station))) :-
    probe_ctx(C), gauge_tests(T),
    step(no_couplant_film, C, [], [], T, auto, [Choice|_]).

test(empty_station_isolated, true(Choice == isolated(empty_couplant_station))) :-
    probe_ctx(C), gauge_tests(T),
    step(no_couplant_film, C, [], [check_couplant_station-empty], T, auto, [Choice|_]).

test(doubled_reading_worn_probe, true(Choice == isolated(worn_probe(us_probe_1)))) :-
    probe_ctx(C), gauge_tests(T),
    step(doubled_thickness, C, [], [read_cal_block-doubled], T, auto, [Choice|_]).

test(doubled_reading_good_probe_is_the_part, true(Choice == isolated(thin_section))) :-
    probe_ctx(C), gauge_tests(T),
    step(doubled_thickness, C, [], [read_cal_block-ok], T, auto, [Choice|_]).

test(implausible_reading_good_probe_is_out_of_tolerance, true(Choice == isolated(out_of_tolerance))) :-
    probe_ctx(C), gauge_tests(T),
    step(implausible_thickness, C, [], [read_cal_block-ok], T, auto, [Choice|_]).

test(timeout_is_the_controller, true(Choice == isolated(controller_not_answering))) :-
    step(controller_timeout, [], [], [query_controller-silent], [query_controller-12.0], auto, [Choice|_]).

test(dirty_window, true(Choice == isolated(dirty_window(slra_1)))) :-
    C = [slra=slra_1, device=slra_1],
    step(too_few_pixels, C, [], [scan_cal_block-too_few_pixels, clean_and_scan_cal_block-ok],
         [scan_cal_block-15.0, clean_and_scan_cal_block-25.0, rescan_second_standoff-4.0], auto, [Choice|_]).

test(a_dirty_window_or_a_failed_laser_is_told_by_wiping_it, true(Choice == test(clean_and_scan_cal_block))) :-
    C = [slra=slra_1, device=slra_1],
    step(too_few_pixels, C, [], [scan_cal_block-too_few_pixels],
         [scan_cal_block-15.0, clean_and_scan_cal_block-25.0, rescan_second_standoff-4.0], auto, [Choice|_]).

test(failed_laser, true(Choice == isolated(slra_failed(slra_1)))) :-
    C = [slra=slra_1, device=slra_1],
    step(too_few_pixels, C, [], [clean_and_scan_cal_block-too_few_pixels],
         [scan_cal_block-15.0, clean_and_scan_cal_block-25.0, rescan_second_standoff-4.0], auto, [Choice|_]).

test(a_view_that_cannot_see_is_no_displaced_part, true(Choice == isolated(view_cannot_measure))) :-
    C = [slra=slra_1, device=slra_1],
    step(out_of_view, C, [], [rescan_second_standoff-fails_again, measure_reference_feature-ok],
         [rescan_second_standoff-4.0, measure_reference_feature-8.0], auto, [Choice|_]).

test(out_of_view_asks_the_part_before_a_person_is_called, true(Choice == test(measure_reference_feature))) :-
    C = [slra=slra_1, device=slra_1],
    step(out_of_view, C, [], [rescan_second_standoff-fails_again],
         [rescan_second_standoff-4.0, measure_reference_feature-8.0], auto, [Choice|_]).

test(a_second_view_that_sees_it_is_an_occlusion, true(Choice == isolated(occlusion))) :-
    C = [slra=slra_1, device=slra_1],
    step(out_of_view, C, [], [rescan_second_standoff-ok, measure_reference_feature-ok],
         [rescan_second_standoff-4.0, measure_reference_feature-8.0], auto, [Choice|_]).

test(a_test_that_bumps_too_finds_the_obstacle_at_the_arm, true(Choice == isolated(obstacle_at_arm))) :-
    step(bump, [], [], [measure_reference_feature-bump], [measure_reference_feature-8.0], auto, [Choice|_]).

test(a_reference_feature_in_place_leaves_an_obstacle_on_the_way, true(Choice == isolated(obstacle))) :-
    step(bump, [], [], [measure_reference_feature-ok], [measure_reference_feature-8.0], auto, [Choice|_]).

test(nothing_left_to_separate, true(Choice = unresolved([_, _, _, _]))) :-
    probe_ctx(C),
    step(no_echo, C, [], [], [], auto, [Choice|_]).

test(isolated_for_kb_why, true(Cause == broken_probe(us_probe_1))) :-
    probe_ctx(C),
    isolated(no_echo, C, [read_cal_block-no_echo], Cause).

test(unknown_method, error(type_error(_, _))) :-
    problem_tree([1.0], [], fastest, _, _).

:- end_tests(diagnosis).
