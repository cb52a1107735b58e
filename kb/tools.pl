:- module(tools,
          [ measurement_kind/1,         % ?Kind
            feature_kind/1,             % ?FeatureKind
            tool_rule/5,                % ?Rule, ?ToolType, ?Kind, ?FeatureKind, ?Conditions
            tool_type_measures/2,       % ?ToolType, ?Kind
            preferred_tool_type/2,      % +Kind, -ToolType
            prefer/2,                   % ?BetterRule, ?WorseRule
            prefer_tool/2,              % ?BetterHow, ?WorseHow
            candidate_rules/3,          % +Kind, +FeatureKind, -Rules
            candidate_tool_types/3,     % +Kind, +FeatureKind, -ToolTypes
            condition_fails/3,          % +Condition, +Facts, -Reason
            rule_applies/3,             % +Rule, +Facts, -Reason
            tool_of_type/3,             % +ToolType, -Tool, -How
            select_tool/5,              % +Kind, +FeatureKind, +Facts, -Choice, -Why
            select_tools/2              % +Requests, -Choices
          ]).

/** <module> Tool selection: which tool performs which measurement

The Sequence Planner partitions the measurements by the tool that will take them (the
seed's "set of rules coded in MRS for tool selection").  The knowledge has three layers,
as in MRS:

  * Object-level rules, tool_rule/5: a tool *type* can perform a *kind* of measurement
    on a *kind* of feature when some conditions hold, e.g. the ultrasonic probe measures
    a web thickness on a pocket floor when the probe can touch the surface there.
  * Meta-level preferences, prefer/2: which rule wins when two apply (the SLRA's rule
    for a rib width over the ultrasonic one), and prefer_tool/2: which physical tool of
    a type to take (the one in the arm's hand, then the primary, then its spare).
  * The world model (kb/world.pl) decides which physical tool of a type is usable now:
    a broken, worn or missing tool is not; its spare is, when the spare is.

The facts about one measurement are an ARGUMENT, a list computed by the caller from the
part's geometry, so that one call can decide a thousand measurements (select_tools/2):

  | fact                      | meaning                                               |
  |---------------------------|-------------------------------------------------------|
  | reach(ToolType, Verdict)  | the arm's reach test for the tool pose that this      |
  |                           | measurement needs with a tool of ToolType: `reachable`|
  |                           | or the reason it is not (`too_far`, `wrist_bend`, ...)|
  | pose(ToolType, Verdict)   | the same from the inverse kinematics / path planner,  |
  |                           | when known                                            |
  | placed(ToolType, Verdict) | the Geometric Reasoner's MKB: `placed`, or why it     |
  |                           | could not place a tool of ToolType for the measurement|
  |                           | (`contact_blocked`: the probe on the point collides at|
  |                           | every roll and arm branch; `approach_blocked`, ...)   |

A condition holds unless a fact refutes it: with no facts at all, select_tool/5 answers
from the rules and the world model alone (so `ita kb why` can be asked about any kind).

A choice is `use(ToolType, Tool, Rule)` or `cannot(Reason)`; Why lists how it came about:
`chosen(Rule, How)` (How is `held`, `primary` or `spare_for(Tool)`) and
`rejected(Rule, Reason)` for each more preferred rule that did not apply.  Reasons are
`no_rule(Kind, FeatureKind)`, `unreachable(ToolType, Verdict)`,
`no_pose(ToolType, Verdict)`, `not_placed(ToolType, Verdict)` and
`no_working_tool(ToolType)`.

Nothing runs at load time.
*/

:- use_module(library(error)).
:- use_module(library(lists)).
:- use_module(library(apply)).
:- use_module(library(aggregate)).
:- use_module(world, [tool/1, type/2, spare_of/2, usable/3, holding/2]).


                 /*******************************
                 *         VOCABULARY           *
                 *******************************/

%!  measurement_kind(?Kind) is nondet.
%
%   Kind is a kind of measurement (the spelling of ita.specs.MeasurementKind).

measurement_kind(web_thickness).
measurement_kind(flange_thickness).
measurement_kind(hole_diameter).
measurement_kind(hole_position).
measurement_kind(flange_height).
measurement_kind(flange_width).
measurement_kind(stiffener_height).
measurement_kind(stiffener_width).
measurement_kind(edge_distance).

%!  feature_kind(?FeatureKind) is nondet.
%
%   FeatureKind is a kind of part feature (ita.part.model.FeatureKind), or `unknown`
%   for a measurement of a part without a feature model (any rule for its kind may
%   then apply).

feature_kind(pocket).
feature_kind(stiffener).
feature_kind(flange).
feature_kind(hole).
feature_kind(unknown).


                 /*******************************
                 *      OBJECT-LEVEL RULES      *
                 *******************************/

%!  tool_rule(?Rule, ?ToolType, ?Kind, ?FeatureKind, ?Conditions:list) is nondet.
%
%   Rule says: a tool of ToolType can perform a measurement of Kind on a feature of
%   FeatureKind when every one of Conditions holds (see condition_fails/3):
%
%     * `probe_can_touch`: the ultrasonic probe's tip can be put on the surface the
%       measurement needs, its axis along the surface normal (for a thickness, the spec
%       point; for a rib's width, a point on the rib's side wall);
%     * `bent_probe_can_touch`: the same for the probe bent 90 degrees (`us_bent`): its
%       shaft along the normal, its holder and the arm across it, beside the wall;
%     * `slra_can_view`: the SLRA can be put on the normal at a stand-off in its working
%       range, looking at the point.

% Thicknesses: ultrasonic contact, through the material (the web's back face is datum A,
% clamped to the fixture: no camera sees it).
tool_rule(us_web_thickness,    us_tool,   web_thickness,    pocket,    [probe_can_touch]).
tool_rule(us_flange_thickness, us_tool,   flange_thickness, flange,    [probe_can_touch]).
% A flange wall the probe cannot touch without the arm or the probe meeting the part
% (the MKB finds its contact pose colliding at every roll and arm branch: the default
% bulkhead's bottom outer flange walls FT-OFL01/02/15/16-W1) is touched by the probe
% bent 90 degrees, its holder running along the wall.
tool_rule(us_bent_flange_thickness, us_bent, flange_thickness, flange, [bent_probe_can_touch]).
% A rib's width is a thickness too: from its side wall with the probe, or from above
% with the SLRA (the two edges of the rib's top face).
tool_rule(us_rib_width,        us_tool,   stiffener_width,  stiffener, [probe_can_touch]).
tool_rule(slra_rib_width,      slra_tool, stiffener_width,  stiffener, [slra_can_view]).
% Holes, heights, widths and edge distances: the SLRA's range image.
tool_rule(slra_hole_diameter,  slra_tool, hole_diameter,    hole,      [slra_can_view]).
tool_rule(slra_hole_position,  slra_tool, hole_position,    hole,      [slra_can_view]).
tool_rule(slra_edge_distance,  slra_tool, edge_distance,    hole,      [slra_can_view]).
tool_rule(slra_flange_height,  slra_tool, flange_height,    flange,    [slra_can_view]).
tool_rule(slra_flange_width,   slra_tool, flange_width,     flange,    [slra_can_view]).
tool_rule(slra_rib_height,     slra_tool, stiffener_height, stiffener, [slra_can_view]).


%!  tool_type_measures(?ToolType, ?Kind) is nondet.
%
%   Some rule lets a tool of ToolType take measurements of Kind (on some feature).
%   Each pair once.

tool_type_measures(ToolType, Kind) :-
    setof(T-K, R^F^C^tool_rule(R, T, K, F, C), Pairs),
    member(ToolType-Kind, Pairs).

%!  preferred_tool_type(+Kind, -ToolType) is semidet.
%
%   ToolType is the tool type of the most preferred rule for measurements of Kind on a
%   feature of any kind (candidate_rules/3 with `unknown`): the tool a reach test of
%   Kind should assume.  Fails when no rule measures Kind.
%
%   @error domain_error(measurement_kind, Kind) for an unknown kind

preferred_tool_type(Kind, ToolType) :-
    candidate_rules(Kind, unknown, [Rule|_]),
    tool_rule(Rule, ToolType, _, _, _).


                 /*******************************
                 *    META-LEVEL PREFERENCES    *
                 *******************************/

%!  prefer(?BetterRule, ?WorseRule) is nondet.
%
%   When both rules apply to a measurement, BetterRule wins.  The SLRA takes a rib's
%   width from the same range image that gives the rib's height at that point, without
%   couplant or a contact move; the probe on the side wall is the fallback.

prefer(slra_rib_width, us_rib_width).
% The bent probe only where the straight one cannot: one tool change more, and the
% cell has no spare bent probe.
prefer(us_flange_thickness, us_bent_flange_thickness).

%!  prefer_tool(?BetterHow, ?WorseHow) is nondet.
%
%   Between usable physical tools of one type: the one the arm holds (no tool change)
%   over the primary tool, the primary over a spare.  How is `held`, `primary` or
%   `spare`.

prefer_tool(held, primary).
prefer_tool(held, spare).
prefer_tool(primary, spare).


                 /*******************************
                 *          CONDITIONS          *
                 *******************************/

%!  condition_fails(+Condition, +Facts:list, -Reason) is semidet.
%
%   A fact of Facts refutes Condition, for Reason.  Fails when the condition holds
%   (no fact refutes it).
%
%   @error domain_error(tool_condition_name, Condition) for an unknown condition

condition_fails(Condition, Facts, Reason) :-
    must_be(list, Facts),
    (   condition_tool(Condition, ToolType)
    ->  pose_refuted(ToolType, Facts, Reason)
    ;   domain_error(tool_condition_name, Condition)
    ).

condition_tool(probe_can_touch, us_tool).
condition_tool(bent_probe_can_touch, us_bent).
condition_tool(slra_can_view, slra_tool).

pose_refuted(ToolType, Facts, unreachable(ToolType, Verdict)) :-
    memberchk(reach(ToolType, Verdict), Facts),
    Verdict \== reachable,
    !.
pose_refuted(ToolType, Facts, no_pose(ToolType, Verdict)) :-
    memberchk(pose(ToolType, Verdict), Facts),
    Verdict \== reachable,
    !.
pose_refuted(ToolType, Facts, not_placed(ToolType, Verdict)) :-
    memberchk(placed(ToolType, Verdict), Facts),
    Verdict \== placed.

%!  rule_applies(+Rule, +Facts:list, -Reason) is det.
%
%   Reason is `applies` when every condition of Rule holds for Facts, else the
%   reason of the first condition that fails.
%
%   @error existence_error(tool_rule, Rule) for an unknown rule

rule_applies(Rule, Facts, Reason) :-
    must_be(atom, Rule),
    (   tool_rule(Rule, _, _, _, Conditions)
    ->  true
    ;   existence_error(tool_rule, Rule)
    ),
    first_failure(Conditions, Facts, Reason).

first_failure([], _, applies).
first_failure([C|Cs], Facts, Reason) :-
    (   condition_fails(C, Facts, Reason0)
    ->  Reason = Reason0
    ;   first_failure(Cs, Facts, Reason)
    ).


                 /*******************************
                 *      CANDIDATES, TOOLS       *
                 *******************************/

%!  candidate_rules(+Kind, +FeatureKind, -Rules:list) is det.
%
%   Rules are the rules for measurements of Kind on a feature of FeatureKind, most
%   preferred first (prefer/2); a rule no other candidate is preferred to comes before
%   the rest, ties in the order of the rule base.  FeatureKind `unknown` matches every
%   rule of Kind.
%
%   @error domain_error(measurement_kind, Kind) for an unknown kind
%   @error domain_error(feature_kind, FeatureKind) for an unknown feature kind

candidate_rules(Kind, FeatureKind, Rules) :-
    must_be_kind(Kind),
    must_be_feature_kind(FeatureKind),
    findall(Rule, rule_for(Kind, FeatureKind, Rule), Rules0),
    by_preference(Rules0, Rules).

rule_for(Kind, unknown, Rule) :-
    !,
    tool_rule(Rule, _, Kind, _, _).
rule_for(Kind, FeatureKind, Rule) :-
    tool_rule(Rule, _, Kind, FeatureKind, _).

by_preference([], []).
by_preference(Rules, [Best|Rest]) :-
    Rules = [_|_],
    (   select(Best, Rules, Others),
        \+ ( member(Other, Others), prefer(Other, Best) )
    ->  true
    ;   Rules = [Best|Others]               % a preference cycle: keep the base's order
    ),
    by_preference(Others, Rest).

%!  candidate_tool_types(+Kind, +FeatureKind, -ToolTypes:list) is det.
%
%   ToolTypes are the tool types of the candidate rules (candidate_rules/3) for
%   measurements of Kind on a feature of FeatureKind, most preferred first, each once:
%   every type a resequencing may move such a measurement to.
%
%   @error domain_error(measurement_kind, Kind) for an unknown kind
%   @error domain_error(feature_kind, FeatureKind) for an unknown feature kind

candidate_tool_types(Kind, FeatureKind, ToolTypes) :-
    candidate_rules(Kind, FeatureKind, Rules),
    findall(T, ( member(R, Rules), tool_rule(R, T, _, _, _) ), Types0),
    list_to_set(Types0, ToolTypes).

%!  tool_of_type(+ToolType, -Tool, -How) is semidet.
%
%   Tool is the physical tool of ToolType the arm should use now, and How says why
%   it is that one: `held` (the arm holds it), `primary` (the cell's own tool of that
%   type) or `spare_for(Primary)` (Primary is not usable).  Only usable tools qualify
%   (world:usable/3: available and liftable); among them prefer_tool/2 decides.  Fails
%   when no tool of ToolType is usable.
%
%   @error domain_error(tool_type, ToolType) for a type that has no tools

tool_of_type(ToolType, Tool, How) :-
    must_be(atom, ToolType),
    (   tool(Some), type(Some, ToolType)
    ->  true
    ;   domain_error(tool_type, ToolType)
    ),
    findall(Rank-(T-H), usable_tool(ToolType, T, H, Rank), Found),
    keysort(Found, [_-(Tool-How)|_]).

usable_tool(ToolType, Tool, How, Rank) :-
    type(Arm, arm),
    usable(Arm, ToolType, Tool),
    tool_role(Arm, Tool, Role, How),
    role_rank(Role, Rank).

tool_role(Arm, Tool, held, held) :-
    holding(Arm, Tool),
    !.
tool_role(_, Tool, spare, spare_for(Primary)) :-
    spare_of(Tool, Primary),
    !.
tool_role(_, _, primary, primary).

% Rank of a role: how many roles are preferred to it.
role_rank(Role, Rank) :-
    aggregate_all(count, prefer_tool(_, Role), Rank).


                 /*******************************
                 *           SELECTION          *
                 *******************************/

%!  select_tool(+Kind, +FeatureKind, +Facts:list, -Choice, -Why:list) is det.
%
%   Choice is the tool for a measurement of Kind on a feature of FeatureKind, given
%   the Facts about it: `use(ToolType, Tool, Rule)` from the most preferred rule that
%   applies and has a usable tool, or `cannot(Reason)` when none does (Reason is that
%   of the most preferred candidate rule).  Why lists `rejected(Rule, Reason)` for each
%   more preferred candidate that lost and, for a use, `chosen(Rule, How)`.  A fact
%   `unmeasurable(Reason)` (the feature the measurement names is not on the part's mesh,
%   ita.part.infer) makes it `cannot(unmeasurable(Reason))` whatever the rules say.
%
%   @error domain_error(measurement_kind, Kind) for an unknown kind
%   @error domain_error(feature_kind, FeatureKind) for an unknown feature kind
%   @error type_error(list, Facts) when Facts is not a list

select_tool(Kind, FeatureKind, Facts, Choice, Why) :-
    must_be(list, Facts),
    candidate_rules(Kind, FeatureKind, Rules),
    (   memberchk(unmeasurable(Reason), Facts)
    ->  Choice = cannot(unmeasurable(Reason)),
        Why = []
    ;   Rules == []
    ->  Choice = cannot(no_rule(Kind, FeatureKind)),
        Why = []
    ;   try_rules(Rules, Facts, Choice, Why)
    ).

try_rules([Rule|Rules], Facts, Choice, Why) :-
    tool_rule(Rule, ToolType, _, _, _),
    rule_applies(Rule, Facts, Applies),
    (   Applies == applies,
        tool_of_type(ToolType, Tool, How)
    ->  Choice = use(ToolType, Tool, Rule),
        Why = [chosen(Rule, How)]
    ;   rejection(Applies, ToolType, Reason),
        (   Rules == []
        ->  Choice = cannot(Reason),
            Why = [rejected(Rule, Reason)]
        ;   try_rules(Rules, Facts, Choice0, Why0),
            first_reason(Choice0, Reason, Choice),
            Why = [rejected(Rule, Reason)|Why0]
        )
    ).

rejection(applies, ToolType, no_working_tool(ToolType)) :- !.
rejection(Reason, _, Reason).

% When no rule wins, the most preferred candidate's reason is the one to report.
first_reason(use(T, Tool, R), _, use(T, Tool, R)).
first_reason(cannot(_), Reason, cannot(Reason)).

%!  select_tools(+Requests:list, -Choices:list) is det.
%
%   Decide many measurements in one call: for each `request(Id, Kind, FeatureKind,
%   Facts)` of Requests, Choices has `choice(Id, Choice, Why)` as select_tool/5 gives
%   them, in the same order.
%
%   @error type_error(list, Requests) when Requests is not a list
%   @error type_error(request, R) for an element that is not a request/4 term

select_tools(Requests, Choices) :-
    must_be(list, Requests),
    maplist(select_one, Requests, Choices).

select_one(Request, choice(Id, Choice, Why)) :-
    (   nonvar(Request),
        Request = request(Id, Kind, FeatureKind, Facts)
    ->  select_tool(Kind, FeatureKind, Facts, Choice, Why)
    ;   type_error(request, Request)
    ).


                 /*******************************
                 *            CHECKS            *
                 *******************************/

must_be_kind(Kind) :-
    must_be(atom, Kind),
    (   measurement_kind(Kind)
    ->  true
    ;   domain_error(measurement_kind, Kind)
    ).

must_be_feature_kind(FeatureKind) :-
    must_be(atom, FeatureKind),
    (   feature_kind(FeatureKind)
    ->  true
    ;   domain_error(feature_kind, FeatureKind)
    ).
