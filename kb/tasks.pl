:- module(tasks,
          [ job/3,                      % ?Name, ?Tasks, ?Description
            operator/4,                 % ?Head, ?Pre, ?Del, ?Add
            method/4                    % ?Name, ?Task, ?Pre, ?Subtasks
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
  - `handle_exception(Spec)`: the Exception Handler diagnoses the failure, puts the
    cell right and measures again;
  - `record(Spec)`: the result to the archive (or held pending its network or webs),
    with the others of its frame;
  - `settle_pending`, `decide_pending`: pending results decided when they can be, and
    all of them at the end;
  - `record_leftovers`: what was never handed out is recorded so;
  - `report_cell`: the cell's state from its reference artifacts (a cell_check event);
  - `end_run(Status)`.

*Attached procedures* (`call(Goal)` in a precondition) are answered by the Top Level's
tools through the bridge (py_bridge:attached/3): the Sequence Planner's next step
from a position of the sequence plan (`next_measurement/3`, `nothing_left/2`), whether
a measurement is still to do (`to_measure/1`: the frame of another may have measured
it since) and whether a probe must read the block before it (`calibration_due/2`).
The Top Level checks an action's preconditions again just before carrying it out.

*Observed facts* the Top Level adds to the state when it sees them: `failed(Spec)`
(the round trip ended in an exception), `interrupted`, `stopped`, `alarm` (so many
measurements in a row not done).  Each makes the rest of the plan wrong, so the
Top Level plans again from there.

A new job is a `job/3` fact and the methods of its tasks; `ita inspect --task NAME`
runs it and `ita tasks` lists them.
*/

:- use_module(library(lists)).

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

operator(record_unplaceable,        [], [], []).
operator(note_resequence(_Cursor),  [], [], []).
operator(calibrate_probe(P),        [], [], [calibrated(P)]).
operator(measure(Spec, _Tool, _G),  [call(to_measure(Spec))], [], []).
operator(handle_exception(S),       [failed(S)], [failed(S)], []).
operator(record(S),                 [not(failed(S))], [], []).
operator(settle_pending,            [], [], []).
operator(decide_pending,            [], [], []).
operator(record_leftovers,          [], [], []).
operator(report_cell,               [], [], []).
operator(end_run(Status),           [], [], [ended(Status)]).

%!  method(?Name, ?Task, ?Pre:list, ?Subtasks:list) is nondet.
%
%   Task may be done by the ordered Subtasks when Pre holds; tried in the order written.

% -- a whole part -----------------------------------------------------------------------
method(in_sequence, inspect_part, [],
       [record_unplaceable, measure_rest(0), close_run]).

% -- what a run left unproven: the run holds those measurements alone ----------------------
method(in_sequence, reinspect, [],
       [measure_rest(0), close_run]).

% -- the cell against its reference artifacts (the run holds the tooling holes' specs) -----
method(artifacts, cell_check, [call(probes(Probes))],
       [read_blocks(Probes), measure_rest(0), report_cell, close_run]).

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
method(round_trip, measure_spec(Spec, Tool, Group), [],
       [measure(Spec, Tool, Group), conclude(Spec)]).

method(halted, conclude(_Spec), [stopped], []).
method(recovered, conclude(Spec), [failed(Spec)],
       [handle_exception(Spec), record(Spec), settle_pending]).
method(recorded, conclude(Spec), [not(failed(Spec))],
       [record(Spec), settle_pending]).

% -- the end of a run ---------------------------------------------------------------------
method(stopped, close_run, [stopped], [end_run(stopped)]).
method(alarmed, close_run, [not(stopped), alarm], [end_run(stopped)]).
method(interrupted, close_run, [not(stopped), not(alarm), interrupted], [end_run(interrupted)]).
method(completed, close_run, [not(stopped), not(alarm), not(interrupted)],
       [decide_pending, record_leftovers, end_run(completed)]).


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
