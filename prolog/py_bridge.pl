:- module(py_bridge,
          [ py_run/5,                   % +Module, +Goal, +Reported, +Limit, -Reply
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
