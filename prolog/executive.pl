:- module(executive,
          [ step_commands/2,            % +Actions, -Commands
            step_command/2              % +Action, -Command
          ]).

/** <module> The operators' side of the Plan Executive/Monitor

The Plan Executive (ita/executive/) turns each step of a plan into a command for one
device stream.  What it sends, to which stream, and what it expects back are the
operator's Figure 3 fields in kb/operators.pl:

    command(Stream, Message, Reply, Result)

  - Stream: the operator's command_stream, e.g. `command_stream(path_planner, t3)` (the
    arm, through the Path Planner, which also runs the ultrasonic gauge) or
    `command_stream(vision, slra_1)` (the SLRA, through Vision);
  - Message: the message pattern with the step's bindings, e.g.
    `'MEASURE'(min_value(meas(b)), max_value(meas(b)))`; its qualitative parameters are
    for the Geometric Reasoner;
  - Reply: the normal reply expected, e.g. `'VALUE'(Val)`;
  - Result: what the step reports once the reply has bound Reply's variables, e.g.
    `dimension(b, us_probe_1, Val, 0.0)`.

The variables that Reply and Result share are numbered (numbervars/3, from 0 within
each command), so that they cross the bridge as `'$VAR'(N)` and stay shared.

The executive asks for all the steps of a plan in one call, step_commands/2.
*/

:- use_module(library(apply)).
:- use_module(library(error)).
:- use_module(library(lists)).
:- use_module('../kb/operators', [static_operator/2]).


%!  step_commands(+Actions:list, -Commands:list) is det.
%
%   Commands are the commands of the steps Actions (ground operator instances such as
%   `us_measure(us_probe_1, t3, b)`), one `command(Stream, Message, Reply, Result)` per
%   action, in the same order (see step_command/2).
%
%   @error type_error(list, Actions) if Actions is not a list
%   @error as step_command/2 for a bad action

step_commands(Actions, Commands) :-
    must_be(list, Actions),
    maplist(step_command, Actions, Commands).

%!  step_command(+Action, -Command) is det.
%
%   Command is `command(Stream, Message, Reply, Result)` of the ground operator
%   instance Action: its command_stream, message_pattern, reply_pattern and
%   result_pattern fields, with the variables of Reply and Result numbered from 0.
%
%   @error instantiation_error if Action is not ground
%   @error type_error(callable, Action) if Action is not an atom or compound
%   @error existence_error(operator, Action) if no static operator has that name and
%   format
%   @error existence_error(operator_field(Field), Action) if the operator lacks one of
%   the four fields

step_command(Action, Command) :-
    must_be(callable, Action),
    (   ground(Action)
    ->  true
    ;   instantiation_error(Action)
    ),
    (   static_operator(Action, Fields)
    ->  true
    ;   existence_error(operator, Action)
    ),
    field(command_stream, Action, Fields, Stream),
    field(message_pattern, Action, Fields, Message),
    field(reply_pattern, Action, Fields, Reply),
    field(result_pattern, Action, Fields, Result),
    Command = command(Stream, Message, Reply, Result),
    numbervars(Command, 0, _).

field(Name, Action, Fields, Value) :-
    Entry =.. [Name, Value0],
    (   memberchk(Entry, Fields)
    ->  Value = Value0
    ;   existence_error(operator_field(Name), Action)
    ).
