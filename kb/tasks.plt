:- begin_tests(tasks_better_way).

% the rules that choose how a reinspection measures a result again

test(other_sensor_for_a_rib_width) :-
    better_way(earlier(uncertain, slra_tool, stiffener_width, 'SLRA calibration (reference workpieces)', 1),
               [alt(us_tool, us_probe_1)], Way),
    Way == other_sensor(us_probe_1).

test(no_other_sensor_of_the_same_accuracy) :-
    % the bent probe is the same gauge: no gain; a flange thickness is measured as before
    better_way(earlier(uncertain, us_tool, flange_thickness, none, 1), [alt(us_bent, us_probe_90)], Way),
    Way == same_way.

test(more_frames_for_a_network_position) :-
    better_way(earlier(uncertain, slra_tool, hole_position, 'network (frame poses and rim fits)', 1), [], Way),
    Way == more_frames(16).

test(more_frames_for_a_pose_datum_position) :-
    better_way(earlier(uncertain, slra_tool, hole_position, 'arm pose and rim fit (mean of 16 frames)', 16), [],
               Way),
    Way == more_frames(64).

test(calibration_does_not_average_away) :-
    better_way(earlier(uncertain, slra_tool, hole_diameter, 'SLRA calibration (reference workpieces)', 1), [],
               Way),
    Way == same_way.

test(not_done_is_tried_again) :-
    better_way(earlier(not_done, slra_tool, hole_diameter, none, 1), [], Way),
    Way == same_way.

:- end_tests(tasks_better_way).

:- use_module('../prolog/htn', [htn_plan/5]).

:- begin_tests(tasks_method_choice).

% method_choice/3 explains the planner's choice: it must agree with prolog/htn.pl

test(completed) :-
    method_choice(close_run, [], chosen(Method, _, Rejected)),
    Method == completed,
    Rejected == [rejected(stopped, stopped), rejected(alarmed, alarm), rejected(interrupted, interrupted)].

test(alarm) :-
    method_choice(close_run, [alarm], chosen(alarmed, Subtasks, [rejected(stopped, stopped)])),
    Subtasks == [check_cell, end_run(stopped)].

test(a_last_check_that_found_the_cell_wrong_measures_again) :-
    method_choice(finish_run, [remeasuring], chosen(Method, Subtasks, _)),
    Method == measure_again, Subtasks == [requeued, measure_rest(0), close_run].

test(same_as_the_planner, [forall(member(Facts, [[], [alarm], [stopped], [interrupted], [interrupted, alarm]]))]) :-
    method_choice(close_run, Facts, chosen(Method, _, _)),
    htn_plan(tasks, Facts, [close_run], [], plan(_, tree(_, [decomposed(_, close_run, Planned, _, _)|_]), _)),
    Method == Planned.

test(attached_procedure_answered) :-
    method_choice(measure_spec(s1, slra_1, 2),
                  [reinspecting, answer(to_measure(s1)),
                   answer(earlier(s1, earlier(uncertain, slra_tool, hole_position, 'network (frame poses and rim fits)', 1))),
                   answer(alternatives(s1, []))],
                  chosen(Method, Subtasks, _)),
    Method == more_accurate,
    Subtasks == [probe_ready(s1, more_frames(16)), measure_again(s1, more_frames(16), 2), conclude(s1)].

test(not_reinspecting) :-
    method_choice(measure_spec(s1, us_probe_1, 1), [answer(to_measure(s1))], chosen(Method, _, Rejected)),
    Method == round_trip,
    memberchk(rejected(more_accurate, reinspecting), Rejected).

test(unanswered_attached_procedure) :-
    method_choice(measure_spec(s1, us_probe_1, 1), [], chosen(Method, _, _)),
    Method == done_already.

:- end_tests(tasks_method_choice).
