:- begin_tests(tools, [setup(reset_world), cleanup(reset_world)]).

:- use_module(tools).
:- use_module(world).

% One reachable fact list for both tool types: nothing refutes any condition.
all_reachable([reach(us_tool, reachable), reach(slra_tool, reachable)]).

chosen_type(Kind, Feature, Type, Rule) :-
    all_reachable(Facts),
    select_tool(Kind, Feature, Facts, use(Type, _, Rule), _).

% --- every measurement kind on its feature kind ------------------------------------

test(web_thickness, true(T-R == us_tool-us_web_thickness)) :-
    chosen_type(web_thickness, pocket, T, R).
test(flange_thickness, true(T-R == us_tool-us_flange_thickness)) :-
    chosen_type(flange_thickness, flange, T, R).
test(hole_diameter, true(T-R == slra_tool-slra_hole_diameter)) :-
    chosen_type(hole_diameter, hole, T, R).
test(hole_position, true(T-R == slra_tool-slra_hole_position)) :-
    chosen_type(hole_position, hole, T, R).
test(edge_distance, true(T-R == slra_tool-slra_edge_distance)) :-
    chosen_type(edge_distance, hole, T, R).
test(flange_height, true(T-R == slra_tool-slra_flange_height)) :-
    chosen_type(flange_height, flange, T, R).
test(flange_width, true(T-R == slra_tool-slra_flange_width)) :-
    chosen_type(flange_width, flange, T, R).
test(stiffener_height, true(T-R == slra_tool-slra_rib_height)) :-
    chosen_type(stiffener_height, stiffener, T, R).
test(stiffener_width_prefers_slra, true(T-R == slra_tool-slra_rib_width)) :-
    chosen_type(stiffener_width, stiffener, T, R).

test(every_kind_has_a_rule, true(Missing == [])) :-
    findall(K, ( measurement_kind(K), \+ tool_rule(_, _, K, _, _) ), Missing).

test(unknown_feature_kind_uses_the_kind_alone, true(T == us_tool)) :-
    chosen_type(web_thickness, unknown, T, _).

test(no_rule_for_kind_on_that_feature, true(C-W == cannot(no_rule(web_thickness, hole))-[])) :-
    select_tool(web_thickness, hole, [], C, W).

% --- physical tools: primary, spare, held ------------------------------------------

test(primary_tool, true(Tool-Why == us_probe_1-[chosen(us_web_thickness, primary)])) :-
    select_tool(web_thickness, pocket, [], use(_, Tool, _), Why).

test(broken_probe_uses_its_spare,
     [ setup(set_tool_condition(us_probe_1, broken)), cleanup(reset_world),
       true(Tool-How == us_probe_2-spare_for(us_probe_1)) ]) :-
    select_tool(web_thickness, pocket, [], use(_, Tool, _), [chosen(_, How)]).

test(missing_slra_uses_its_spare,
     [ setup(set_location(slra_1, missing)), cleanup(reset_world),
       true(Tool == slra_2) ]) :-
    select_tool(hole_diameter, hole, [], use(_, Tool, _), _).

test(broken_probe_without_spare_cannot,
     [ setup(( set_tool_condition(us_probe_1, broken),
               set_tool_condition(us_probe_2, worn) )),
       cleanup(reset_world),
       true(C == cannot(no_working_tool(us_tool))) ]) :-
    select_tool(web_thickness, pocket, [], C, _).

test(held_tool_preferred_over_primary,
     [ setup(set_location(us_probe_2, on_arm(t3))), cleanup(reset_world),
       true(Tool-How == us_probe_2-held) ]) :-
    tool_of_type(us_tool, Tool, How).

test(no_usable_tool_of_type_fails,
     [ setup(( set_tool_condition(slra_1, broken), set_location(slra_2, missing) )),
       cleanup(reset_world), fail ]) :-
    tool_of_type(slra_tool, _, _).

% --- preferences and conditions ----------------------------------------------------

test(candidates_in_preference_order, true(Rules == [slra_rib_width, us_rib_width])) :-
    candidate_rules(stiffener_width, stiffener, Rules).

test(rib_width_falls_back_to_probe_without_slra,
     [ setup(( set_tool_condition(slra_1, broken), set_tool_condition(slra_2, broken) )),
       cleanup(reset_world),
       true(C-W == use(us_tool, us_probe_1, us_rib_width)-
                   [rejected(slra_rib_width, no_working_tool(slra_tool)),
                    chosen(us_rib_width, primary)]) ]) :-
    select_tool(stiffener_width, stiffener, [], C, W).

test(rib_width_falls_back_when_slra_cannot_view,
     true(R == us_rib_width)) :-
    select_tool(stiffener_width, stiffener, [reach(slra_tool, inside_part)],
                use(_, _, R), _).

test(unreachable_reports_the_reach_verdict,
     true(C == cannot(unreachable(us_tool, too_far)))) :-
    select_tool(web_thickness, pocket, [reach(us_tool, too_far)], C, _).

test(no_pose_reports_the_planner_verdict,
     true(C == cannot(no_pose(slra_tool, collision)))) :-
    select_tool(hole_position, hole, [pose(slra_tool, collision)], C, _).

test(both_rib_rules_fail_reports_the_preferred_reason,
     true(C == cannot(unreachable(slra_tool, too_far)))) :-
    select_tool(stiffener_width, stiffener,
                [reach(slra_tool, too_far), reach(us_tool, wrist_bend)], C, _).

test(rule_applies, true(R == applies)) :-
    rule_applies(us_web_thickness, [reach(slra_tool, too_far)], R).

test(condition_holds_without_facts, fail) :-
    condition_fails(probe_can_touch, [], _).

% --- the probe bent 90 degrees: where the straight probe cannot touch -----------------

% What the MKB says of the default bulkhead's four bottom outer flange walls: the
% straight probe's contact pose collides at every roll and arm branch, the bent one's
% does not.
blocked_wall([reach(us_tool, reachable), reach(us_bent, reachable), reach(slra_tool, reachable),
              pose(us_tool, reachable), pose(us_bent, reachable),
              placed(us_tool, contact_blocked), placed(us_bent, placed)]).

test(flange_thickness_prefers_the_straight_probe,
     true(C-W == use(us_tool, us_probe_1, us_flange_thickness)-[chosen(us_flange_thickness, primary)])) :-
    select_tool(flange_thickness, flange, [placed(us_tool, placed), placed(us_bent, placed)], C, W).

test(blocked_flange_wall_gets_the_bent_probe,
     true(C-W == use(us_bent, us_probe_90, us_bent_flange_thickness)-
                 [rejected(us_flange_thickness, not_placed(us_tool, contact_blocked)),
                  chosen(us_bent_flange_thickness, primary)])) :-
    blocked_wall(Facts),
    select_tool(flange_thickness, flange, Facts, C, W).

test(the_four_blocked_walls_of_the_bulkhead_get_the_bent_probe,
     true(Tools == [us_probe_90, us_probe_90, us_probe_90, us_probe_90])) :-
    blocked_wall(Facts),
    Ids = ['FT-OFL01-W1', 'FT-OFL02-W1', 'FT-OFL15-W1', 'FT-OFL16-W1'],
    findall(request(Id, flange_thickness, flange, Facts), member(Id, Ids), Requests),
    select_tools(Requests, Choices),
    findall(T, member(choice(_, use(us_bent, T, _), _), Choices), Tools).

test(blocked_for_both_probes_cannot_with_the_straight_probes_reason,
     true(C == cannot(not_placed(us_tool, contact_blocked)))) :-
    select_tool(flange_thickness, flange,
                [placed(us_tool, contact_blocked), placed(us_bent, approach_blocked)], C, _).

test(bent_probe_too_far_cannot,
     true(C == cannot(not_placed(us_tool, contact_blocked)))) :-
    select_tool(flange_thickness, flange,
                [placed(us_tool, contact_blocked), reach(us_bent, too_far)], C, _).

test(no_bent_probe_for_a_web, true(C == cannot(not_placed(us_tool, contact_blocked)))) :-
    select_tool(web_thickness, pocket, [placed(us_tool, contact_blocked)], C, _).

test(broken_bent_probe_cannot,
     [ setup(set_tool_condition(us_probe_90, broken)), cleanup(reset_world),
       true(C == cannot(not_placed(us_tool, contact_blocked))) ]) :-
    blocked_wall(Facts),
    select_tool(flange_thickness, flange, Facts, C, _).

test(straight_probes_broken_flange_goes_to_the_bent_probe,
     [ setup(( set_tool_condition(us_probe_1, broken), set_tool_condition(us_probe_2, broken) )),
       cleanup(reset_world), true(T == us_probe_90) ]) :-
    select_tool(flange_thickness, flange, [], use(us_bent, T, _), _).

test(candidate_types_of_flange_thickness, true(Ts == [us_tool, us_bent])) :-
    candidate_tool_types(flange_thickness, flange, Ts).

test(bent_probe_not_taken_for_the_straight_type, true(Ts == [us_probe_1, us_probe_2])) :-
    findall(T, ( tool_of_type(us_tool, T, _) ; set_tool_condition(us_probe_1, broken),
                                                tool_of_type(us_tool, T, _) ), Ts),
    reset_world.

% --- the batch call ----------------------------------------------------------------

test(select_tools_batch,
     true(Cs == [choice(a, use(us_tool, us_probe_1, us_web_thickness),
                        [chosen(us_web_thickness, primary)]),
                 choice(b, cannot(unreachable(slra_tool, too_far)),
                        [rejected(slra_hole_diameter, unreachable(slra_tool, too_far))])])) :-
    select_tools([request(a, web_thickness, pocket, []),
                  request(b, hole_diameter, hole, [reach(slra_tool, too_far)])], Cs).

test(select_tools_empty, true(Cs == [])) :-
    select_tools([], Cs).

% --- tool types per kind ------------------------------------------------------------

test(rib_width_by_both_types, true(Ts == [slra_tool, us_tool])) :-
    setof(T, tool_type_measures(T, stiffener_width), Ts).
test(preferred_type_of_rib_width, true(T == slra_tool)) :-
    preferred_tool_type(stiffener_width, T).
test(preferred_type_of_thickness, true(T == us_tool)) :-
    preferred_tool_type(web_thickness, T).
test(candidate_types_of_rib_width, true(Ts == [slra_tool, us_tool])) :-
    candidate_tool_types(stiffener_width, stiffener, Ts).
test(candidate_types_of_hole, true(Ts == [slra_tool])) :-
    candidate_tool_types(hole_position, hole, Ts).
test(preferred_type_of_unknown_kind, error(domain_error(measurement_kind, depth))) :-
    preferred_tool_type(depth, _).

% --- bad input ---------------------------------------------------------------------

test(unknown_kind, error(domain_error(measurement_kind, depth))) :-
    select_tool(depth, pocket, [], _, _).
test(unknown_feature_kind, error(domain_error(feature_kind, boss))) :-
    select_tool(web_thickness, boss, [], _, _).
test(facts_not_a_list, error(type_error(list, nope))) :-
    select_tool(web_thickness, pocket, nope, _, _).
% A measurement whose feature is not on the part's mesh cannot be done, with that reason,
% even where every rule's conditions hold.
test(unmeasurable_feature, Choice == cannot(unmeasurable('no hole at (1.0, 2.0, 3.0)'))) :-
    select_tool(hole_diameter, unknown, [reach(slra_tool, reachable), unmeasurable('no hole at (1.0, 2.0, 3.0)')],
                Choice, _).

test(bad_request, error(type_error(request, foo(1)))) :-
    select_tools([foo(1)], _).
test(unknown_condition, error(domain_error(tool_condition_name, smell))) :-
    condition_fails(smell, [], _).
test(unknown_rule, error(existence_error(tool_rule, nope))) :-
    rule_applies(nope, [], _).
test(unknown_tool_type, error(domain_error(tool_type, drill))) :-
    tool_of_type(drill, _, _).

:- end_tests(tools).
