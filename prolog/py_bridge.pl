:- module(py_bridge,
          [ py_run/5,                   % +Module, +Goal, +Reported, +Limit, -Reply
            attached/3,                 % +Name, +Args, -Result
            load_source_files/2,        % +Files, -Diagnostics
            file_module/2               % +File, -Module
          ]).

/** <module> The Prolog side of the Python bridge

Python (ita/logic/bridge.py) calls Prolog through one deterministic predicate,
py_run/5.  Python builds its arguments with SWI-Prolog's C interface, term by term
(`PL_put_chars`, `PL_cons_functor_v`, `PL_cons_list`...): values arrive as data,
never as text that is read or run, so an atom with quotes or spaces is just an atom.

The reply is text, written with quoted(true) and ignore_ops(true) (functional
notation, no operators, '$VAR'(N) as itself) so that a small tokenizer
(ita/logic/terms.py) reads it back: `[Values1, Values2, ...]`, the values of the
reported variables in each solution, or `error(MessageString, GoalString)` when the
goal raised an exception.  Prolog strings come back to Python as plain strings,
like atoms.

The other direction: attached/3 is how Prolog calls Python.  A goal
`attached(Name, Args, Result)` is answered by the Python function that the ITA
process attached under Name for the duration of its call (`KnowledgeBase.attached()`,
ita/logic/attached.py).  The arguments go to Python as text written like a reply and
read by the same tokenizer; the solutions come back as terms that Python builds with
the C interface, as it builds its goals.  The Python side is the foreign predicate
py_attached_call/3, which bridge.py registers in this module when it starts Prolog:
in any other process (a plain `swipl`, the sandbox of `ita kb query`) there is none,
and attached/3 raises an existence error.

load_source_files/2 loads files while a message hook collects every error and warning
with its file, line and column; on any error it unloads the whole batch again, so a
caller never works with a half-loaded knowledge base.
*/

:- use_module(library(apply)).
:- use_module(library(lists)).
:- use_module(library(error)).
:- use_module(library(solution_sequences)).

:- thread_local collecting/0.
:- thread_local collected/5.

:- multifile user:message_hook/3.
:- dynamic user:message_hook/3.
:- multifile prolog:error_message//1.

%   While load_source_files/2 runs in this thread, errors and warnings are recorded
%   (and not printed); at all other times the hook lets messages through untouched.
user:message_hook(Term, Kind, _Lines) :-
    collecting,
    memberchk(Kind, [error, warning]),
    message_location(Term, File, Line, Column),
    message_text(Term, Text),
    assertz(collected(Kind, File, Line, Column, Text)).


                 /*******************************
                 *        GENERIC CALLS         *
                 *******************************/

%!  py_run(+Module, +Goal, +Reported:list, +Limit, -Reply:string) is det.
%
%   Reply is the text of the list of the values of Reported (a list of variables of
%   Goal) in all (Limit `all`) or the first Limit (a positive integer) solutions of
%   Module:Goal, or of `error(Message, GoalText)` (two strings) when the call raised
%   an exception, a bad Module, Goal or Limit included.

py_run(Module, Goal, Reported, Limit, Reply) :-
    reply_options(Options),
    catch(( check_request(Module, Goal, Limit),
            solutions_text(Limit, Module:Goal, Reported, Options, Reply)
          ),
          Error,
          ( format(string(GoalText), "~q", [Module:Goal]),
            error_reply(Error, GoalText, Result),
            format(string(Reply), "~W", [Result, Options])
          )).

%   Each solution is written as soon as it is found, so a variable left unbound has
%   one name in every solution, as in the goal.  The goal's own output is not
%   redirected.
solutions_text(1, Goal, Reported, Options, Reply) :- !,
    (   call(Goal)
    ->  format(string(Reply), "[~W]", [Reported, Options])
    ;   Reply = "[]"
    ).
solutions_text(Limit, Goal, Reported, Options, Reply) :-
    findall(Text,
            ( limited(Limit, Goal),
              format(string(Text), "~W", [Reported, Options])
            ),
            Texts),
    with_output_to(string(Reply), write_list_text(Texts)).

write_list_text([]) :-
    write('[]').
write_list_text([Text|Texts]) :-
    write('['),
    write(Text),
    forall(member(More, Texts), (write(','), write(More))),
    write(']').

check_request(Module, Goal, Limit) :-
    atom(Module),
    callable(Goal),
    (   Limit == all
    ->  true
    ;   integer(Limit),
        Limit > 0
    ),
    !.
check_request(Module, Goal, Limit) :-
    must_be(atom, Module),
    must_be(callable, Goal),
    (   Limit == all
    ->  true
    ;   must_be(positive_integer, Limit)
    ).

limited(all, Goal) :- !, call(Goal).
limited(Limit, Goal) :- limit(Limit, Goal).

error_reply(Error, GoalText, error(Message, GoalText)) :-
    message_text(Error, Message).

%   How replies are written: quoted, in functional notation, '$VAR'(N) as itself.
%   (The other options that matter, dotlists(false), portray(false),
%   character_escapes(true) and max_depth(0), are the defaults.)
reply_options([quoted(true), ignore_ops(true), brace_terms(false), numbervars(false)]).


                 /*******************************
                 *     ATTACHED PROCEDURES      *
                 *******************************/

%!  attached(+Name:atom, +Args:list, -Result) is nondet.
%
%   Result is a solution of the Python procedure attached under Name, called on the
%   terms of Args.  A semidet procedure has no solution or one, a nondet one any number;
%   they are computed together before the first is returned, so no choice point is
%   left after the last.  Unbound variables of Args reach Python as variables that it
%   cannot bind: Result is the only output.  Raises
%   `existence_error(attached_procedure, Name/N)`, N the length of Args, when no
%   procedure Name is attached for the goals of this thread (or in a process that is
%   not ITA's), `attached_procedure_error(Name/N, PythonType, Message)` when the
%   Python function raised an exception, and
%   `permission_error(call, attached_procedure, outside_a_bridge_call)` when called
%   by a thread that Prolog started rather than by a goal that Python runs.

attached(Name, Args, Result) :-
    must_be(atom, Name),
    must_be(list, Args),
    (   current_predicate(py_attached_call/3)
    ->  reply_options(Options),
        format(string(Text), "~W", [Args, Options]),
        py_attached_call(Name, Text, Solutions),
        member(Result, Solutions)
    ;   length(Args, Arity),
        existence_error(attached_procedure, Name/Arity)
    ).

prolog:error_message(existence_error(attached_procedure, Name/Arity)) -->
    [ 'No attached procedure ~w/~w: none of that name is attached for the goals of this thread'-
      [Name, Arity] ].
prolog:error_message(attached_procedure_error(Name/Arity, Type, Message)) -->
    [ 'Attached procedure ~w/~w raised ~w: ~w'-[Name, Arity, Type, Message] ].
prolog:error_message(permission_error(call, attached_procedure, outside_a_bridge_call)) -->
    [ 'Attached procedures answer only the goals that Python runs through the bridge, \c
       in the thread that runs them (not a thread that Prolog started)' ].


                 /*******************************
                 *            LOADING           *
                 *******************************/

%!  load_source_files(+Files:list(atom), -Diagnostics:list) is det.
%
%   Load every file of Files (absolute paths) and collect the errors and warnings
%   printed while doing so as terms `diagnostic(Kind, File, Line, Column, Message)`,
%   Kind being `error` or `warning`.  When any diagnostic is an error, every file of
%   Files that was not loaded before is unloaded again: nothing stays half-loaded.  A
%   file already loaded and unchanged is not loaded a second time.

load_source_files(Files, Diagnostics) :-
    must_be(list(atom), Files),
    retractall(collected(_, _, _, _, _)),
    exclude(source_file, Files, NewFiles),
    setup_call_cleanup(
        assertz(collecting),
        maplist(load_one, Files),
        retractall(collecting)),
    findall(diagnostic(Kind, File, Line, Column, Text),
            retract(collected(Kind, File, Line, Column, Text)),
            Diagnostics),
    (   memberchk(diagnostic(error, _, _, _, _), Diagnostics)
    ->  maplist(unload_quietly, NewFiles)
    ;   true
    ).

load_one(File) :-
    catch(load_files(user:File, [if(changed), imports([])]), Error,
          print_message(error, Error)).

unload_quietly(File) :-
    catch(unload_file(File), _, true).

%!  file_module(+File:atom, -Module:atom) is semidet.
%
%   Module is the module that the loaded source File defines.  Fails for a file that
%   is not loaded or is not a module file.

file_module(File, Module) :-
    must_be(atom, File),
    source_file_property(File, module(Module)).


                 /*******************************
                 *           MESSAGES           *
                 *******************************/

message_location(error(_, file(File, Line, Column, _)), File, Line, Column) :- !.
message_location(error(_, stream(Stream, Line, Column, _)), File, Line, Column) :-
    catch(stream_property(Stream, file_name(File)), _, fail), !.
message_location(_, File, Line, 0) :-
    source_location(File, Line), !.
message_location(_, '', 0, 0).

%   One-line text of a message without the location prefix.
message_text(Term, Text) :-
    (   Term = error(Formal, _)
    ->  Plain = error(Formal, _)
    ;   Plain = Term
    ),
    (   catch('$messages':translate_message(Plain, Lines, []), _, fail)
    ->  with_output_to(string(Text0),
                       print_message_lines(current_output, '', Lines)),
        split_string(Text0, "\n", " \t", Parts),
        exclude(==(""), Parts, NonEmpty),
        atomic_list_concat(NonEmpty, ' ', Atom),
        atom_string(Atom, Text)
    ;   format(string(Text), "~q", [Term])
    ).
