:- module(tasks,
          [ job/3,                      % ?Name, ?Tasks, ?Description
            operator/4,                 % ?Head, ?Pre, ?Del, ?Add
            method/4,                   % ?Name, ?Task, ?Pre, ?Subtasks
            better_way/3,               % +Earlier, +Alternatives, -Way
            more_accurate/3,            % ?BetterToolType, ?ToolType, ?Kind
            falls_with_frames/1,        % ?TermPrefix
            interim_check/1,            % ?Every
            check_with/3,               % ?ToolType, ?Test, ?Found
            method_choice/3             % +Task, +Facts, -Choice
          ]).

/** <module> The Top Level's jobs, as a task network for the HTN planner

The seed's own wish for its Top Level: "a high-level planner that can call on
special-purpose functions such as the current sequence planner as tools".  This file
is the knowledge of that planner (prolog/htn.pl: a total-order HTN planner, SHOP2
family): the jobs a cell can be given, the methods that decompose them, and the
primitive tasks the Top Level carries out.  The Top Level plans a job ahead, carries
out the plan's actions one by one and plans again from the state it finds when an
action's outcome differs from what the plan expected (an exception, an interrupt, a
tool that broke).

*Primitive tasks* (`operator(Head, Pre, Del, Add)`) are what the Top Level executes,
each with one piece of Python behind it (ita/toplevel/actions.py):

  - `record_unplaceable`: what the Sequence Planner put in its cannot-be-done group is
    recorded so;
  - `note_resequence(Cursor)`: the sequence plan was remade at that point (an event);
  - `calibrate_probe(Probe)`: the probe reads the calibration block;
  - `measure(Spec, Tool, Group)`: one measurement's round trip (plan, execute);
  - `measure_again(Spec, Way, Group)`: the same, the way better_way/3 chose to measure
    again what an earlier run left unproven: `same_way`, `more_frames(N)` (the SLRA
    takes N frames, each after its own approach, and Vision averages them) or
    `other_sensor(Tool)`;
  - `handle_exception(Spec)`: the Exception Handler diagnoses the failure, puts the
    cell right and measures again (a retry that fails with an exception of its own is
    observed as `failed(Spec)` again, and diagnosed in turn: at most 3 in all);
  - `record(Spec)`: the result to the archive (or held pending its network or webs),
    with the others of its frame;
  - `settle_pending`, `decide_pending`: pending results decided when they can be, and
    all of them at the end;
  - `record_leftovers`: what was never handed out is recorded so;
  - `report_cell`: the cell's state from its reference artifacts (a cell_check event);
  - `check_cell`: the interim check of the cell against its reference artifacts with the
    tool in hand (interim_check/1, check_with/3); when it finds the arm drifted or the
    part moved, the Exception Handler diagnoses it and puts it right, and the results
    recorded since the last good check are taken out of the archive (an event keeps
    them) and measured again (the measurements go on from where they are, those first);
  - `check_if_due`: `check_cell` when the cadence of interim_check/1 says it is due
    (asked when the action is carried out: a plan made ahead cannot know when);
  - `requeued`: the measurements since the last good check are back in the sequence
    plan (nothing to do: the fact `remeasuring` goes);
  - `retake_not_done`: at the end, the measurements this run left not done after a fault
    it then put right (not those whose cause cannot be put right in the cell, nor those
    Vision cannot measure in their view) are taken
    out of the archive and measured once more (observed `remeasuring`), once per run;
  - `end_run(Status)`.

*Attached procedures* (`call(Goal)` in a precondition) are answered by the Top Level's
tools through the bridge (py_bridge:attached/3): the Sequence Planner's next step
from a position of the sequence plan (`next_measurement/3`, `nothing_left/2`), whether
a measurement is still to do (`to_measure/1`: the frame of another may have measured
it since), whether a probe must read the block before it (`calibration_due/2`), and in
a reinspection the earlier run's result of a measurement (`earlier/2`) and the other
tools placed for it (`alternatives/2`).
The Top Level checks an action's preconditions again just before carrying it out.

*Given facts*: `reinspecting` (the run measures again what an earlier run left
unproven; `earlier/2` answers for its measurements).

*Observed facts* the Top Level adds to the state when it sees them: `failed(Spec)`
(the round trip ended in an exception), `interrupted`, `stopped`, `alarm` (so many
measurements in a row not done), `remeasuring` (an interim check, or a diagnosis, found
the arm drifted or the part moved: what was measured since the last good check is back
in the sequence plan).  Each makes the rest of the plan wrong, so the
Top Level plans again from there.

A new job is a `job/3` fact and the methods of its tasks; `ita inspect --task NAME`
runs it and `ita tasks` lists them.
*/

:- use_module(library(lists)).
:- use_module(library(apply)).
:- use_module(library(error)).

%!  job(?Name:atom, ?Tasks:list, ?Description:atom) is nondet.
%
%   Name is a job the Top Level can run: the ordered task network Tasks.

job(inspect_part, [inspect_part],
    'measure every measurement of the run once, in the sequence plan\'s order (the default)').
job(reinspect, [reinspect],
    'measure again what a run (--from RUN) left unproven: uncertain, does not conform, not done').
job(cell_check, [cell_check],
    'measure the cell\'s reference artifacts: each probe on the calibration block, the tooling holes with the SLRA').

%!  operator(?Head, ?Pre:list, ?Del:list, ?Add:list) is nondet.
%
%   The primitive task Head is applicable when Pre holds; it deletes Del and adds Add.

operator(register_part,             [], [], [registered]).
operator(record_unplaceable,        [], [], []).
operator(note_resequence(_Cursor),  [], [], []).
operator(calibrate_probe(P),        [], [], [calibrated(P)]).
operator(measure(Spec, _Tool, _G),  [call(to_measure(Spec))], [], []).
operator(measure_again(Spec, _Way, _G), [call(to_measure(Spec))], [], []).
operator(handle_exception(S),       [failed(S)], [failed(S)], []).
operator(record(S),                 [not(failed(S))], [], []).
operator(settle_pending,            [], [], []).
operator(decide_pending,            [], [], []).
operator(record_leftovers,          [], [], []).
operator(report_cell,               [], [], []).
operator(check_cell,                [], [], []).
operator(check_if_due,              [], [], []).
operator(requeued,                  [remeasuring], [remeasuring], []).
operator(retake_not_done,           [], [], []).
operator(end_run(Status),           [], [], [ended(Status)]).

%!  method(?Name, ?Task, ?Pre:list, ?Subtasks:list) is nondet.
%
%   Task may be done by the ordered Subtasks when Pre holds; tried in the order written.

% -- a whole part: located on its datums first (no fixture puts it where the model says) ----
method(in_sequence, inspect_part, [],
       [register_part, record_unplaceable, measure_rest(0), close_run]).

% -- what a run left unproven: the run holds those measurements alone ----------------------
method(in_sequence, reinspect, [],
       [register_part, measure_rest(0), close_run]).

% -- the cell against its reference artifacts (the run holds the tooling holes' specs) -----
% the report counts every artifact: what is pending is decided and what was never measured
% recorded first (close_run's own do nothing then)
method(artifacts, cell_check, [call(probes(Probes))],
       [read_blocks(Probes), register_part, measure_rest(0), decide_pending, check_cell, record_leftovers,
        report_cell, close_run]).

method(none_left, read_blocks([]), [], []).
method(each_probe, read_blocks([Probe|Probes]), [], [calibrate_probe(Probe), read_blocks(Probes)]).

% -- the measurements still to do, from a position (Cursor) of the sequence plan ---------
method(halted, measure_rest(_Cursor), [or([[interrupted], [stopped], [alarm]])], []).
method(next_measurement, measure_rest(Cursor),
       [ not(interrupted), not(stopped), not(alarm),
         call(next_measurement(Cursor, step(Spec, Tool, Group, Resequenced), Next)) ],
       [resequenced(Resequenced), measure_spec(Spec, Tool, Group), measure_rest(Next)]).
method(nothing_left, measure_rest(Cursor),
       [not(interrupted), not(stopped), not(alarm), call(nothing_left(Cursor, Resequenced))],
       [resequenced(Resequenced)]).

method(as_planned, resequenced([]), [], []).
method(remade, resequenced([Cursor|Cursors]), [], [note_resequence(Cursor), resequenced(Cursors)]).

% -- one measurement ----------------------------------------------------------------------
method(halted, measure_spec(_Spec, _Tool, _Group), [or([[interrupted], [stopped], [alarm]])], []).
method(done_already, measure_spec(Spec, _Tool, _Group), [not(call(to_measure(Spec)))], []).
method(calibrate_first, measure_spec(Spec, Tool, Group),
       [not(calibrated(Tool)), call(calibration_due(Spec, Tool))],
       [calibrate_probe(Tool), measure_spec(Spec, Tool, Group)]).
method(more_accurate, measure_spec(Spec, _Tool, Group),
       [ reinspecting, call(earlier(Spec, Earlier)), call(alternatives(Spec, Alternatives)),
         call(better_way(Earlier, Alternatives, Way)), Way \= same_way ],
       [probe_ready(Spec, Way), measure_again(Spec, Way, Group), conclude(Spec)]).
method(round_trip, measure_spec(Spec, Tool, Group), [],
       [measure(Spec, Tool, Group), conclude(Spec)]).

% -- the other sensor of a reinspection may be a probe that has not read the block yet ------
method(calibrate_first, probe_ready(Spec, other_sensor(Tool)),
       [not(calibrated(Tool)), call(calibration_due(Spec, Tool))], [calibrate_probe(Tool)]).
method(ready, probe_ready(_Spec, _Way), [], []).

method(halted, conclude(_Spec), [stopped], []).
% after the handler, conclude again: its retry may have failed with a new exception (the
% Top Level then observes failed(Spec) once more), which is diagnosed in turn
method(recovered, conclude(Spec), [failed(Spec)],
       [handle_exception(Spec), conclude(Spec)]).
method(recorded, conclude(Spec), [not(failed(Spec))],
       [record(Spec), settle_pending, check_if_due]).

% -- the end of a run ---------------------------------------------------------------------
method(stopped, close_run, [stopped], [end_run(stopped)]).
% what was measured since the last good interim check is recorded once a last check passes
% (a STOP leaves it to be measured again by `ita continue`)
method(alarmed, close_run, [not(stopped), alarm], [check_cell, end_run(stopped)]).
method(interrupted, close_run, [not(stopped), not(alarm), interrupted], [check_cell, end_run(interrupted)]).
method(completed, close_run, [not(stopped), not(alarm), not(interrupted)],
       [decide_pending, check_cell, retake_not_done, finish_run]).
method(measure_again, finish_run, [remeasuring], [requeued, measure_rest(0), close_run]).
method(done, finish_run, [not(remeasuring)], [record_leftovers, end_run(completed)]).


                 /*******************************
                 *     THE CELL CHECKS ITSELF   *
                 *******************************/

%!  interim_check(?Every) is nondet.
%
%   The Top Level checks the cell against its reference artifacts when Every has passed
%   since its last good check: `seconds(S)` of simulated time, `measurements(N)` results.
%   It also checks when a tool of a type with no reference reading yet is first in hand
%   (the SLRA's first view of tooling hole B is the reference for the later ones), and at
%   the end of a run.  "Reasoning can do little to replace perception when it comes to
%   determining the state of an environment" (the seed): an arm that drifts or a part
%   that moves raises no exception of its own, and a result taken meanwhile looks as
%   good as any; so what was measured since the last good check is measured again when a
%   check (or a diagnosis) finds the arm or the part off.

interim_check(seconds(600)).
interim_check(measurements(500)).

%!  check_with(?ToolType, ?Test, ?Found) is nondet.
%
%   With a tool of ToolType in hand the check is Test of kb/faults.pl; when it shows
%   something, Found is the exception the Exception Handler diagnoses:
%   `position_drift_detected` (tooling hole B is not where the reference reading saw
%   it), `misaligned` (the probe's reading of the calibration block walks off).

check_with(slra_tool, measure_reference_feature, position_drift_detected).
check_with(us_tool,   read_cal_block,            misaligned).


                 /*******************************
                 *   MEASURING AGAIN, BETTER    *
                 *******************************/

%!  better_way(+Earlier, +Alternatives:list, -Way) is det.
%
%   The way to measure again a result an earlier run left unproven, so that its
%   uncertainty is smaller where a smaller one can be had.  Earlier is
%   `earlier(Decision, ToolType, Kind, Largest, Frames)`: the earlier decision
%   (`uncertain`, `does_not_conform`, `not_done`), the type of the tool that took it,
%   the kind of measurement, the name of its uncertainty budget's largest term (`none`
%   when it has no value) and the frames it averaged.  Alternatives: `alt(ToolType,
%   Tool)` for each other tool the measurement knowledge base placed for it and the
%   world model has usable.  In this order:
%
%     1. `other_sensor(Tool)`: a tool of a type more_accurate/3 says measures this kind
%        better;
%     2. `more_frames(N)`: an SLRA result whose largest term is one that is a new draw
%        at every approach (falls_with_frames/1): four times the frames it had, at least
%        16 and at most 64, which halves that term or better.  A term that is the same in
%        every frame (the SLRA's calibration, the edge model, the neighbours' own
%        positions) does not average away: more frames would not help;
%     3. `same_way`: measure it as before (a result not done is tried again).
%
%   A second stand-off is not offered: the SLRA's calibration on reference workpieces
%   holds at its nominal stand-off only, so a size from another would lose it.

better_way(earlier(_, ToolType, Kind, _, _), Alternatives, other_sensor(Tool)) :-
    member(alt(Better, Tool), Alternatives),
    more_accurate(Better, ToolType, Kind),
    !.
better_way(earlier(_, slra_tool, _, Largest, Frames), _, more_frames(N)) :-
    atom(Largest),
    falls_with_frames(Prefix),
    sub_atom(Largest, 0, _, _, Prefix),
    !,
    N is min(64, max(16, 4 * Frames)).
better_way(_, _, same_way).

%!  more_accurate(?BetterToolType, ?ToolType, ?Kind) is nondet.
%
%   For measurements of Kind, a tool of BetterToolType gives a smaller uncertainty
%   than one of ToolType.  A rib's width: the probe's thickness reading on its side
%   wall (U about 0.004 mm, the gauge's resolution and its calibration on the block)
%   against the SLRA's two edges from above (U 0.02 mm or more, the edge model and the
%   calibration's scatter).

more_accurate(us_tool, slra_tool, stiffener_width).

%!  falls_with_frames(?TermPrefix) is nondet.
%
%   An uncertainty budget term whose name begins with TermPrefix is a new draw at every
%   approach of the arm (its repeatability) or every frame (a fit's noise): the mean of
%   N frames from N approaches divides it by the square root of N.

falls_with_frames('network (frame poses').
falls_with_frames('arm pose').
falls_with_frames('rim fit').
falls_with_frames('edge line fit').
falls_with_frames('the frame\'s own fits').


                 /*******************************
                 *    WHY A METHOD WAS CHOSEN   *
                 *******************************/

%!  method_choice(+Task, +Facts:list, -Choice) is det.
%
%   The method the planner takes for Task in a state holding Facts, and why not the
%   ones written before it: Choice is `chosen(Method, Subtasks, Rejected)` or
%   `none(Rejected)`, Rejected listing `rejected(Method, Literal)` for each method tried
%   before, with the first literal of its preconditions that does not hold.  The
%   literals are those of prolog/htn.pl (facts, `not/1`, `or/1`, `forall/2`, `=`,
%   `\=`, `call/1`).  An attached procedure is answered by a fact `answer(Goal)` among
%   Facts (in a run the Top Level's tools answer it); one that is not so answered is a
%   literal that does not hold.  `ita kb why 'method_choice(close_run, [alarm], C)'`
%   shows the proof.

method_choice(Task, Facts, Choice) :-
    must_be(list, Facts),
    findall(method(Name, Pre, Subtasks), method(Name, Task, Pre, Subtasks), Methods),
    choose(Methods, Facts, [], Choice).

choose([], _, Rejected0, none(Rejected)) :-
    reverse(Rejected0, Rejected).
choose([method(Name, Pre, Subtasks)|Methods], Facts, Rejected0, Choice) :-
    check_lits(Pre, Facts, Verdict),
    (   Verdict = fails(Literal)
    ->  choose(Methods, Facts, [rejected(Name, Literal)|Rejected0], Choice)
    ;   reverse(Rejected0, Rejected),
        Choice = chosen(Name, Subtasks, Rejected)
    ).

%   check_lits(+Lits, +Facts, -Verdict): `holds` with the bindings of the first answer of
%   each literal in turn, or fails(Literal) for the first that does not hold then.
check_lits([], _, holds).
check_lits([L|Ls], Facts, Verdict) :-
    (   once(lit_holds(L, Facts))
    ->  check_lits(Ls, Facts, Verdict)
    ;   Verdict = fails(L)
    ).

lit_holds(not(L), Facts) :- !,
    \+ lits_hold(L, Facts).
lit_holds(or(Alternatives), Facts) :- !,
    member(A, Alternatives),
    lits_hold(A, Facts).
lit_holds(forall(G, T), Facts) :- !,
    forall(lits_hold(G, Facts), lits_hold(T, Facts)).
lit_holds(X = Y, _) :- !,
    X = Y.
lit_holds(X \= Y, _) :- !,
    X \= Y.
lit_holds(call(G), Facts) :- !,
    (   member(answer(G), Facts)
    ;   answered_here(G)
    ).
lit_holds(A, Facts) :-
    member(A, Facts).

lits_hold([], _) :- !.
lits_hold([L|Ls], Facts) :- !,
    lit_holds(L, Facts),
    lits_hold(Ls, Facts).
lits_hold(L, Facts) :-
    lit_holds(L, Facts).

%   answered_here(+Goal): an attached procedure this module answers without the Top
%   Level (better_way/3); the others need an answer(Goal) fact.
answered_here(better_way(E, A, W)) :-
    better_way(E, A, W).


                 /*******************************
                 *      ATTACHED PROCEDURES     *
                 *******************************/

%   next_measurement(+Cursor, -Step, -Next): the Sequence Planner's next measurement
%   after the position Cursor of the sequence plan, step(Spec, Tool, Group,
%   Resequenced), and the position after it; fails when nothing is left.
next_measurement(Cursor, Step, Next) :-
    py_bridge:attached(next_measurement, [Cursor], next(Step, Next)).

%   nothing_left(+Cursor, -Resequenced): nothing is left after Cursor (the positions
%   where the plan was remade on the way, for their events).
nothing_left(Cursor, Resequenced) :-
    py_bridge:attached(nothing_left, [Cursor], Resequenced).

%   to_measure(+Spec): Spec is still to measure in this run (not recorded, not held
%   pending, one of the run's).  False of a measurement the frame of another measured
%   since the plan was made: the Top Level then plans its measure_spec again.
to_measure(Spec) :-
    py_bridge:attached(to_measure, [Spec], true).

%   probes(-Probes): the cell's ultrasonic probes the arm can use now.
probes(Probes) :-
    py_bridge:attached(probes, [], Probes).

%   calibration_due(+Spec, +Tool): Tool is a probe and Spec can be placed for it, so it
%   reads the calibration block before measuring Spec (if not yet calibrated).
calibration_due(Spec, Tool) :-
    py_bridge:attached(calibration_due, [Spec, Tool], true).

%   earlier(+Spec, -Earlier): in a reinspection, the earlier run's result of Spec as
%   better_way/3 takes it.
earlier(Spec, Earlier) :-
    py_bridge:attached(earlier, [Spec], Earlier).

%   alternatives(+Spec, -Alternatives): alt(ToolType, Tool) for each usable tool of
%   another type than the one planned that the MKB placed for Spec.
alternatives(Spec, Alternatives) :-
    py_bridge:attached(alternatives, [Spec], Alternatives).
