:- module(kb_query,
          [ run_query/4,                % +Text, +Modules, +Options, -Result
            with_user_goal/5,           % +Text, +Modules, +Options, :Action, -Result
            term_text/2                 % +Term, -Text
          ]).

/** <module> Run a user's goal against the knowledge bases, safely

A goal typed by a person (`ita kb query`, `ita kb shell`, `ita kb why`) is text.  It is
parsed, checked by library(sandbox) (no shell, no files, no halt, no consult, no
changes to other modules), and run

  - in a temporary module that imports the exported predicates of the knowledge-base
    modules, so it can read them but whatever it asserts vanishes with the module;
  - inside snapshot/1, so even a retract/assert that the sandbox lets through (one
    that a knowledge-base predicate itself performs) is rolled back;
  - under a time limit and an inference limit, so a goal that loops is stopped.

Problems with the user's goal are results, not exceptions: `refused(Reason)`,
`limit_exceeded(Reason)` and `error(Reason)` carry a one-line Reason string.
*/

:- use_module(library(sandbox)).
:- use_module(library(time)).
:- use_module(library(option)).
:- use_module(library(error)).
:- use_module(library(apply)).
:- use_module(library(lists)).
:- use_module(library(solution_sequences)).

:- meta_predicate with_user_goal(+, +, +, 4, -).

%!  run_query(+Text:text, +Modules:list(atom), +Options:list, -Result) is det.
%
%   Run the goal Text against the exports of Modules and collect its solutions.
%   Options are those of with_user_goal/5 and `limit(N)` (default 100), the largest
%   number of solutions to collect.  Result is one of
%
%     - answers(Names, Rows, Truncated): Names lists the goal's variables (those not
%       starting with `_`), each row the values of one solution printed with `~q`,
%       Truncated is `true` when there are more than N solutions, else `false`;
%     - refused(Reason), limit_exceeded(Reason) or error(Reason), see with_user_goal/5.

run_query(Text, Modules, Options, Result) :-
    must_be(list, Options),
    option(limit(Limit), Options, 100),
    must_be(positive_integer, Limit),
    with_user_goal(Text, Modules, Options, collect_rows(Limit), Result).

%!  with_user_goal(+Text:text, +Modules:list(atom), +Options:list, :Action, -Result) is det.
%
%   Parse Text as a goal, check it with the sandbox and run call(Action, Module, Goal,
%   Bindings, Result) in a temporary Module importing the exports of Modules, under
%   snapshot/1 and the limits.  Bindings is the `Name=Var` list of the goal.  Action
%   must be deterministic.  Options:
%
%     - time_limit(+Seconds): CPU-independent wall time limit (default 10)
%     - inference_limit(+Count): inference limit (default 10,000,000)
%
%   Result is Action's result, or `refused(Reason)` (syntax error, unsafe goal,
%   unknown predicate), `limit_exceeded(Reason)` or `error(Reason)` (the goal raised
%   an exception).

with_user_goal(Text, Modules, Options, Action, Result) :-
    must_be(text, Text),
    must_be(list(atom), Modules),
    must_be(list, Options),
    option(time_limit(Time), Options, 10),
    must_be(number, Time),
    (   Time > 0 -> true ; domain_error(positive_number, Time) ),
    option(inference_limit(Inferences), Options, 10_000_000),
    must_be(positive_integer, Inferences),
    parse_goal(Text, Parsed),
    (   Parsed = goal(Goal, Bindings)
    ->  in_temporary_module(Module,
                            import_exports(Modules, Module),
                            guarded(Module, Goal, Bindings,
                                    Time-Inferences, Action, Result))
    ;   Result = Parsed
    ).

parse_goal(Text, Parsed) :-
    catch(term_string(Goal, Text, [variable_names(Bindings)]), Error, true),
    (   nonvar(Error)
    ->  syntax_reason(Error, Reason),
        Parsed = refused(Reason)
    ;   var(Goal)
    ->  Parsed = refused("refused: the goal is a variable; write a goal such as type(X, arm)")
    ;   Goal == end_of_file
    ->  Parsed = refused("refused: empty goal")
    ;   Parsed = goal(Goal, Bindings)
    ).

syntax_reason(error(syntax_error(What), Context), Reason) :- !,
    message_words(error(syntax_error(What), _), Words0),
    (   sub_string(Words0, 0, _, After, "Syntax error: ")
    ->  sub_string(Words0, _, After, 0, Words)
    ;   Words = Words0
    ),
    (   Context = string(_, CharNo), integer(CharNo)
    ->  format(string(Reason), "refused: syntax error: ~w (at character ~d)", [Words, CharNo])
    ;   format(string(Reason), "refused: syntax error: ~w", [Words])
    ).
syntax_reason(Error, Reason) :-
    message_words(Error, Reason).

import_exports(Modules, Into) :-
    forall(( member(Module, Modules),
             module_property(Module, exports(Exports)),
             member(PI, Exports)
           ),
           catch(@(import(Module:PI), Into), _, true)).

guarded(Module, Goal, Bindings, Time-Inferences, Action, Result) :-
    (   catch(safe_goal(Module:Goal), Error, true)
    ->  true
    ;   Error = error(permission_error(call, sandboxed, Goal), sandbox(Goal, []))
    ),
    (   nonvar(Error)
    ->  refusal_reason(Error, Reason),
        Result = refused(Reason)
    ;   run_limited(Module, Goal, Bindings, Time-Inferences, Action, Result)
    ).

run_limited(Module, Goal, Bindings, Time-Inferences, Action, Result) :-
    catch(call_with_time_limit(
              Time,
              call_with_inference_limit(
                  snapshot(call(Action, Module, Goal, Bindings, Result0)),
                  Inferences, Outcome)),
          Error, true),
    (   nonvar(Error)
    ->  exception_result(Error, Time, Result)
    ;   Outcome == inference_limit_exceeded
    ->  format(string(Reason),
               "stopped: the goal used more than ~D inferences (inference limit); \c
                it may loop", [Inferences]),
        Result = limit_exceeded(Reason)
    ;   Result = Result0
    ).

exception_result(time_limit_exceeded, Time, limit_exceeded(Reason)) :- !,
    format(string(Reason),
           "stopped: the goal ran longer than ~w s (time limit); it may loop", [Time]).
exception_result(error(resource_error(Resource), _), _, limit_exceeded(Reason)) :- !,
    format(string(Reason), "stopped: out of ~w; the goal may loop", [Resource]).
exception_result(Error, _, error(Reason)) :-
    message_words(Error, Reason).

%   refusal_reason(+SandboxError, -Reason) gives a one-line reason.
refusal_reason(error(permission_error(call, sandboxed, Culprit), sandbox(_, Path)),
               Reason) :- !,
    strip_module(Culprit, _, Plain),
    term_text(Plain, Text),
    (   database_change(Plain)
    ->  format(string(Reason),
               "refused: ~s would change the knowledge base; queries are read-only",
               [Text])
    ;   Path = [_|_], last(Path, Top)
    ->  strip_module(Top, _, TopPlain),
        functor(TopPlain, TopName, TopArity),
        functor(Plain, Name, Arity),
        format(string(Reason),
               "refused: ~q is not allowed in a query (it calls ~q, which is unsafe)",
               [TopName/TopArity, Name/Arity])
    ;   format(string(Reason), "refused: ~s is not allowed in a query (unsafe)",
               [Text])
    ).
refusal_reason(error(existence_error(procedure, PI), _), Reason) :- !,
    strip_module(PI, _, Plain),
    (   Plain = Name/Arity
    ->  true
    ;   functor(Plain, Name, Arity)
    ),
    format(string(Reason), "refused: unknown predicate ~q", [Name/Arity]).
refusal_reason(error(instantiation_error, _), Reason) :- !,
    Reason = "refused: the goal calls a variable goal (e.g. call(G) with G unbound), \c
              which cannot be checked for safety".
refusal_reason(Error, Reason) :-
    message_words(Error, Words),
    format(string(Reason), "refused: ~w", [Words]).

database_change(Goal) :-
    compound(Goal),
    functor(Goal, Name, _),
    memberchk(Name, [assert, asserta, assertz, retract, retractall, erase,
                     abolish]).

%   collect_rows(+Limit, +Module, +Goal, +Bindings, -Answers) is det.
:- public collect_rows/5.

collect_rows(Limit, Module, Goal, Bindings, answers(Names, Rows, Truncated)) :-
    exclude(anonymous, Bindings, Visible),
    findall(Name, member(Name=_, Visible), Names),
    Limit1 is Limit + 1,
    findall(Row, limit(Limit1, (Module:Goal, row_text(Visible, Row))), Rows0),
    length(Rows0, Count),
    (   Count > Limit
    ->  Truncated = true,
        length(Rows, Limit),
        append(Rows, _, Rows0)
    ;   Truncated = false,
        Rows = Rows0
    ).

anonymous(Name=_) :- sub_atom(Name, 0, _, _, '_').

row_text(Bindings, Row) :-
    findall(Value, member(_=Value, Bindings), Values),
    term_text_list(Values, Row).

term_text_list(Terms, Texts) :-
    copy_term(Terms, Copy, _Goals),
    term_variables(Copy, Vars),
    name_variables(Vars, 1),
    maplist(print_text, Copy, Texts).

%!  term_text(+Term, -Text:string) is det.
%
%   Text is Term written with quotes where needed, free variables shown as `_1`,
%   `_2`, ...: the way query answers and proof steps are printed.

term_text(Term, Text) :-
    term_text_list([Term], [Text]).

name_variables([], _).
name_variables([Var|Vars], N) :-
    format(atom(Name), "_~d", [N]),
    Var = '$VAR'(Name),
    N1 is N + 1,
    name_variables(Vars, N1).

print_text(Term, Text) :-
    format(string(Text), "~W",
           [Term, [quoted(true), numbervars(true), portray(true),
                   spacing(next_argument)]]).

message_words(Term, Words) :-
    (   catch('$messages':translate_message(Term, Lines, []), _, fail)
    ->  with_output_to(string(Text),
                       print_message_lines(current_output, '', Lines)),
        split_string(Text, "\n", " \t", Parts),
        exclude(==(""), Parts, NonEmpty),
        atomic_list_concat(NonEmpty, ' ', Atom),
        atom_string(Atom, Words)
    ;   format(string(Words), "~q", [Term])
    ).
