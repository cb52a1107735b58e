:- use_module(executive).

/*  Tests of the executive's command patterns: each step's stream, message, expected
    reply and result, from the operators of kb/operators.pl.  */

:- begin_tests(executive).

test(arm_move_goes_to_the_path_planner,
     true(C == command(command_stream(path_planner, t3),
                       'MOVE'(approach_point(meas(a)), approach_point(meas(b))),
                       'DONE',
                       moved(t3, approach_point(meas(b)))))) :-
    step_command(move(t3, meas(a), meas(b)), C).

test(ultrasonic_measurement_rides_the_arm_stream_and_shares_its_value,
     true(C == command(command_stream(path_planner, t3),
                       'MEASURE'(min_value(meas(b)), max_value(meas(b))),
                       'VALUE'('$VAR'(0)),
                       dimension(b, us_probe_1, '$VAR'(0), 0.0)))) :-
    step_command(us_measure(us_probe_1, t3, b), C).

test(slra_scan_goes_to_vision,
     true(Stream-Message == command_stream(vision, slra_1)-'SCAN'(patches(meas(b))))) :-
    step_command(slra_scan(slra_1, t3, b), command(Stream, Message, _, _)).

test(two_reply_variables_numbered_in_order,
     true(Reply-Result == 'VALUE'('$VAR'(0), '$VAR'(1))-dimension(b, slra_1, '$VAR'(0), '$VAR'(1)))) :-
    step_command(slra_measure(slra_1, t3, b), command(_, _, Reply, Result)).

test(plan_in_one_call,
     true(Streams == [command_stream(path_planner, t3), command_stream(path_planner, t3),
                      command_stream(vision, slra_1), command_stream(vision, slra_1)])) :-
    step_commands([move_retract(t3, a), move_view(t3, a), slra_scan(slra_1, t3, a),
                   slra_measure(slra_1, t3, a)], Commands),
    findall(S, member(command(S, _, _, _), Commands), Streams).

test(empty_plan, true(Commands == [])) :-
    step_commands([], Commands).

test(unknown_action, error(existence_error(operator, fly(t3)))) :-
    step_command(fly(t3), _).

test(unbound_argument, error(instantiation_error)) :-
    step_command(move(t3, _, home), _).

test(not_a_list, error(type_error(list, move(t3, home, home)))) :-
    step_commands(move(t3, home, home), _).

:- end_tests(executive).
