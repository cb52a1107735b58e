:- module(py_bridge,
          [ py_call/2,                  % +RequestJSON, -ResponseJSON
            load_source_files/2,        % +Files, -Diagnostics
            file_module/2,              % +File, -Module
            json_term/3                 % ?JSON, ?Term, +VarTable
          ]).

/** <module> The Prolog side of the Python bridge

Python (ita/logic/bridge.py) talks to Prolog through one deterministic predicate,
py_call/2, which takes a request and returns a response, both as JSON text.  Values
travel as data, never as query text, so no quoting or injection problem can arise.

The JSON encoding of terms (both directions):

  | Prolog              | JSON                                    |
  |---------------------|-----------------------------------------|
  | atom                | string                                  |
  | number              | number                                  |
  | string              | {"str": Text}                           |
  | list                | array                                   |
  | compound f(A1..An)  | {"functor": "f", "args": [A1, ..., An]} |
  | variable            | {"var": Name}                           |

Prolog strings come back to Python as plain strings, like atoms.

load_source_files/2 loads files while a message hook collects every error and warning
with its file, line and column; on any error it unloads the whole batch again, so a
caller never works with a half-loaded knowledge base.
*/

:- use_module(library(http/json)).
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

%!  py_call(+Request:text, -Response:string) is det.
%
%   Run the goal that Request describes and return all (or the first `limit`)
%   solutions.  Request is JSON text of the form
%   `{"module": M, "name": N, "args": [A1, ...], "limit": L}` where the arguments use
%   the encoding of this module and `limit` is a positive integer or null.  Response is
%   JSON text: `{"solutions": [Bindings, ...]}` where each Bindings object maps the
%   name of every variable of the arguments to its value, or `{"error": Message,
%   "goal": GoalText}` when the goal raised an exception.

py_call(Request, Response) :-
    must_be(text, Request),
    catch(parse_request(Request, Goal, Limit, Vars), Error,
          error_dict(Error, "", Dict)),
    (   var(Dict)
    ->  catch(solutions(Goal, Limit, Vars, Dict), Error2,
              ( format(string(GoalText), "~q", [Goal]),
                error_dict(Error2, GoalText, Dict)
              ))
    ;   true
    ),
    with_output_to(string(Response),
                   json_write_dict(current_output, Dict,
                                   [ width(0),
                                     true(@(true)), false(@(false)), null(@(null))
                                   ])).

parse_request(Request, Module:Goal, Limit, Vars) :-
    atom_json_dict(Request, Dict, [value_string_as(atom)]),
    get_dict(module, Dict, Module), must_be(atom, Module),
    get_dict(name, Dict, Name), must_be(atom, Name),
    get_dict(args, Dict, JArgs), must_be(list, JArgs),
    get_dict(limit, Dict, Limit),
    json_args(JArgs, Args, Vars),
    Goal =.. [Name|Args].

solutions(Goal, Limit, Vars, _{solutions: Solutions}) :-
    findall(Bindings,
            ( limited(Limit, Goal),
              bindings_dict(Vars, Bindings)
            ),
            Solutions).

limited(null, Goal) :- !, call(Goal).
limited(Limit, Goal) :- must_be(positive_integer, Limit), limit(Limit, Goal).

json_args(JArgs, Args, Vars) :-
    foldl(json_arg, JArgs, Args, [], Vars0),
    reverse(Vars0, Vars).

json_arg(JSON, Term, Vars0, Vars) :- json_term(JSON, Term, Vars0-Vars).

bindings_dict(Vars, Dict) :-
    findall(Name-JSON,
            ( member(Name=Var, Vars),
              \+ sub_atom(Name, 0, _, _, '_'),
              term_json(Var, JSON)
            ),
            Pairs),
    dict_pairs(Dict, _, Pairs).

error_dict(Error, GoalText, _{error: Message, goal: GoalText}) :-
    message_text(Error, Message).

%!  json_term(+JSON, -Term, +VarTable) is det.
%!  json_term(-JSON, +Term, +VarTable) is det.
%
%   Translate between the JSON encoding of this module (as read by
%   atom_json_dict/3 with `value_string_as(atom)`) and a Prolog term.  VarTable is a
%   pair `Vars0-Vars` of `Name=Var` lists: variables of the same name share one Prolog
%   variable.  In the mode (-,+) VarTable is ignored and variables are named by
%   their print name.

json_term(JSON, Term, VarTable) :-
    nonvar(JSON), !,
    VarTable = Vars0-Vars,
    json_to_term(JSON, Term, Vars0, Vars).
json_term(JSON, Term, _) :-
    term_json(Term, JSON).

json_to_term(JSON, Term, Vars0, Vars) :-
    (   is_dict(JSON)
    ->  json_dict_to_term(JSON, Term, Vars0, Vars)
    ;   is_list(JSON)
    ->  foldl(json_arg, JSON, Term, Vars0, Vars)
    ;   atomic(JSON)
    ->  Term = JSON, Vars = Vars0
    ;   type_error(json_term, JSON)
    ).

json_dict_to_term(Dict, Var, Vars0, Vars) :-
    get_dict(var, Dict, Name), !,
    must_be(atom, Name),
    (   memberchk(Name=Var0, Vars0)
    ->  Var = Var0, Vars = Vars0
    ;   Vars = [Name=Var|Vars0]
    ).
json_dict_to_term(Dict, String, Vars, Vars) :-
    get_dict(str, Dict, Text), !,
    atom_string(Text, String).
json_dict_to_term(Dict, Term, Vars0, Vars) :-
    get_dict(functor, Dict, Name), !,
    must_be(atom, Name),
    get_dict(args, Dict, JArgs),
    must_be(list, JArgs),
    foldl(json_arg, JArgs, Args, Vars0, Vars),
    compound_name_arguments(Term, Name, Args).
json_dict_to_term(Dict, _, _, _) :-
    domain_error(json_term, Dict).

term_json(Term, JSON) :-
    (   var(Term)
    ->  format(atom(Name), "~p", [Term]), JSON = _{var: Name}
    ;   Term == []
    ->  JSON = []
    ;   is_list(Term)
    ->  maplist(term_json, Term, JSON)
    ;   atom(Term)
    ->  JSON = Term
    ;   number(Term)
    ->  JSON = Term
    ;   string(Term)
    ->  JSON = Term
    ;   compound(Term)
    ->  compound_name_arguments(Term, Name, Args),
        maplist(term_json, Args, JArgs),
        JSON = _{functor: Name, args: JArgs}
    ;   format(string(JSON), "~q", [Term])
    ).


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
