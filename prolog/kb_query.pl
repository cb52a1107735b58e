:- module(kb_query,
          [ run_query/4,                % +Text, +Modules, +Options, -Result
            with_user_goal/5,           % +Text, +Modules, +Options, :Action, -Result
            term_text/2,                % +Term, -Text
            error_text/2,               % +Error, -Text
            goal_hazard/2               % +Goal, -Reason
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

Before library(sandbox) looks at it, goal_hazard/2 refuses what the sandbox lets
through but should not: the message system (print_message/2 and friends translate a
message term with format/2, whose `~@` directive calls any goal, and message hooks),
`~@` in any text of the goal (a format string built at run time starts as text),
format column or repeat counts so large they would fill memory, threads (a thread
outlives snapshot/1), and global variables.  The commands of ITA run this whole
predicate in a child process with operating-system limits (ita/logic/sandbox.py,
kb_sandbox.pl), so a goal that gets past both checks still meets the process's walls.

Problems with the user's goal are results, not exceptions: `refused(Reason)`,
`limit_exceeded(Reason)` and `error(Reason)` carry a one-line Reason string.  A term
the goal produced (an exception, a syntax or refusal reason) is made text by
error_text/2, never by the message system: message translation runs the `format/2`
directives of the term (`~@` runs a goal), after every check of the goal's text.
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
%   number of solutions to collect.  `listing(Name)` and `listing(Name/Arity)` print the
%   clauses of those predicates of Modules (read-only) and answer `true`.  Result is one of
%
%     - answers(Names, Rows, Truncated): Names lists the goal's variables (those not
%       starting with `_`), each row the values of one solution printed with `~q`,
%       Truncated is `true` when there are more than N solutions, else `false`;
%     - refused(Reason), limit_exceeded(Reason) or error(Reason), see with_user_goal/5.

run_query(Text, Modules, Options, Result) :-
    must_be(list, Options),
    option(limit(Limit), Options, 100),
    must_be(positive_integer, Limit),
    (   listing_request(Text, Name, Arity)
    ->  kb_listing(Name, Arity, Modules, Result)
    ;   with_user_goal(Text, Modules, Options, collect_rows(Limit), Result)
    ).

%   listing_request(+Text, -Name, -Arity): Text is `listing(Name)` or
%   `listing(Name/Arity)`, which a query answers read-only by printing the clauses of
%   the knowledge bases' predicates (library(sandbox) refuses listing/1 itself).
listing_request(Text, Name, Arity) :-
    catch(read_goal(Text, Goal, _, end_of_file), _, fail),
    nonvar(Goal),
    Goal = listing(Spec),
    (   atom(Spec)
    ->  Name = Spec
    ;   nonvar(Spec), Spec = Name/Arity, atom(Name), integer(Arity)
    ).

kb_listing(Name, Arity, Modules, Result) :-
    findall(M:Head,
            ( member(M, Modules),
              current_predicate(M:Name/Arity),
              functor(Head, Name, Arity),
              \+ predicate_property(M:Head, imported_from(_)),
              \+ predicate_property(M:Head, foreign)
            ),
            Found),
    (   Found == []
    ->  (   var(Arity) -> Shown = Name ; Shown = Name/Arity ),
        format(string(Reason), "refused: no knowledge-base predicate ~q to list", [Shown]),
        Result = refused(Reason)
    ;   forall(member(M:Head, Found),
               ( functor(Head, _, HeadArity),
                 format("% ~q~n", [M:Name/HeadArity]),
                 forall(catch(clause(M:Head, Body), _, fail), portray_clause((Head :- Body))),
                 nl )),
        Result = answers([], [[]], false)
    ).

%!  with_user_goal(+Text:text, +Modules:list(atom), +Options:list, :Action, -Result) is det.
%
%   Parse Text as a goal, check it with the sandbox and run call(Action, Module, Goal,
%   Bindings, Result) in a temporary Module importing the exports of Modules, under
%   snapshot/1 and the limits.  Bindings is the `Name=Var` list of the goal.  Action
%   must be deterministic.  Options:
%
%     - time_limit(+Seconds): CPU-independent wall time limit (default 10), or `none`
%       when the caller enforces one from outside (the child process of
%       ita/logic/sandbox.py, which may not start the alarm thread)
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
    (   Time == none
    ->  true
    ;   must_be(number, Time),
        (   Time > 0 -> true ; domain_error(positive_number, Time) )
    ),
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
    catch(read_goal(Text, Goal, Bindings, Rest), Error, true),
    (   nonvar(Error)
    ->  syntax_reason(Error, Reason),
        Parsed = refused(Reason)
    ;   var(Goal)
    ->  Parsed = refused("refused: the goal is a variable; write a goal such as type(X, arm)")
    ;   Goal == end_of_file
    ->  Parsed = refused("refused: empty goal")
    ;   Rest \== end_of_file
    ->  Parsed = refused("refused: one goal at a time: there is more text after the full stop \c
                          (join goals with a comma)")
    ;   Parsed = goal(Goal, Bindings)
    ).

%   read_goal(+Text, -Goal, -Bindings, -Rest): Goal is the first term of Text (its
%   full stop may be left out), Rest is end_of_file when nothing follows it, else
%   `more`.
read_goal(Text, Goal, Bindings, Rest) :-
    catch(read_first(Text, Goal, Bindings, Rest), error(syntax_error(end_of_file), _), fail),
    !.
read_goal(Text, Goal, Bindings, Rest) :-
    atomics_to_string([Text, "\n."], Stopped),
    read_first(Stopped, Goal, Bindings, Rest).

read_first(Text, Goal, Bindings, Rest) :-
    setup_call_cleanup(
        open_string(Text, In),
        ( read_term(In, Goal, [variable_names(Bindings), syntax_errors(error)]),
          (   Goal == end_of_file
          ->  Rest = end_of_file
          ;   catch(read_term(In, Next, [syntax_errors(error)]), _, Next = more),
              (   Next == end_of_file -> Rest = end_of_file ; Rest = more )
          )
        ),
        close(In)).

syntax_reason(error(syntax_error(What), Context), Reason) :- !,
    syntax_words(What, Words),
    (   (   Context = string(_, CharNo) ; Context = stream(_, _, _, CharNo) ),
        integer(CharNo)
    ->  format(string(Reason), "refused: syntax error: ~w (at character ~d)", [Words, CharNo])
    ;   format(string(Reason), "refused: syntax error: ~w", [Words])
    ).
syntax_reason(error(resource_error(Resource), _), Reason) :- !,
    format(string(Reason),
           "refused: the goal is too large or nested too deep to read (out of ~w)", [Resource]).
syntax_reason(Error, Reason) :-
    error_text(Error, Words),
    format(string(Reason), "refused: ~s", [Words]).

import_exports(Modules, Into) :-
    forall(( member(Module, Modules),
             module_property(Module, exports(Exports)),
             member(PI, Exports)
           ),
           catch(@(import(Module:PI), Into), _, true)).

guarded(_Module, Goal, _Bindings, _Limits, _Action, refused(Reason)) :-
    goal_hazard(Goal, Reason), !.
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
    Limited = call_with_inference_limit(
                  snapshot(call(Action, Module, Goal, Bindings, Result0)),
                  Inferences, Outcome),
    (   Time == none
    ->  catch(Limited, Error, true)
    ;   catch(call_with_time_limit(Time, Limited), Error, true)
    ),
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
exception_result(error(resource_error(c_stack), _), _, limit_exceeded(Reason)) :- !,
    Reason = "stopped: a term is nested too deep (out of C stack, a resource limit)".
exception_result(error(resource_error(Resource), _), _, limit_exceeded(Reason)) :- !,
    format(string(Reason), "stopped: out of ~w (a resource limit); the goal may loop \c
                            or build a huge term", [Resource]).
exception_result(Error, _, error(Reason)) :-
    error_text(Error, Reason).

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
    error_text(Error, Words),
    format(string(Reason), "refused: ~s", [Words]).

%!  goal_hazard(+Goal, -Reason:string) is semidet.
%
%   True when Goal (a parsed user goal) contains something the query sandbox refuses
%   although library(sandbox) would accept it; Reason is a one-line refusal.  The
%   check is on the whole term, data included, because data can become a goal (a
%   message term, a closure, a format argument).

goal_hazard(Goal, Reason) :-
    sub_term(Sub, Goal),
    sub_hazard(Sub, Reason), !.

sub_hazard(Sub, Reason) :-
    (   atom(Sub) -> Atom = Sub
    ;   compound(Sub) -> compound_name_arity(Sub, Atom, _)
    ),
    denied_name(Atom, Why), !,
    format(string(Reason), "refused: ~q is not allowed in a query (~w)", [Atom, Why]).
sub_hazard(Text, Reason) :-
    (   atom(Text) ; string(Text) ),
    text_hazard(Text, Reason), !.
sub_hazard(Codes, Reason) :-
    is_list(Codes), Codes = [C|_], integer(C),
    catch(string_codes(Text, Codes), _, fail),
    text_hazard(Text, Reason).

text_hazard(Text, Reason) :-
    sub_string(Text, _, _, _, "~@"), !,
    Reason = "refused: the format directive ~@ (it runs a goal) is not allowed in a query".
text_hazard(Text, Reason) :-
    sub_string(Text, Before, _, _, "~"),
    sub_string(Text, Before, _, 0, Rest),
    string_codes(Rest, [0'~|Codes]),
    directive_count(Codes, Count),
    Count > 1_000_000, !,
    format(string(Reason),
           "refused: format count or column ~D is too large (at most 1,000,000)", [Count]).

%   directive_count(+CodesAfterTilde, -Count): the numeric argument of a directive,
%   also after a `c fill character (~`xt~2000|).
directive_count([0'`, _|Codes], Count) :- !,
    directive_count(Codes, Count).
directive_count(Codes, Count) :-
    digits(Codes, Digits),
    Digits \== [],
    number_codes(Count, Digits).
directive_count([0'~|Codes], Count) :-
    directive_count(Codes, Count).
directive_count([C|Codes], Count) :-
    \+ code_type(C, digit),
    C \== 0'~,
    directive_count(Codes, Count).

digits([C|Cs], [C|Ds]) :- code_type(C, digit), !, digits(Cs, Ds).
digits(_, []).

denied_name(print_message, "messages are formatted with goals that can run anything").
denied_name(print_message_lines, "messages are formatted with goals that can run anything").
denied_name(message_to_codes, "messages are formatted with goals that can run anything").
denied_name(translate_message, "messages are formatted with goals that can run anything").
denied_name(message_hook, "message hooks run outside the sandbox").
denied_name(message_property, "message hooks run outside the sandbox").
denied_name(prolog_message, "message hooks run outside the sandbox").
denied_name('$messages', "message internals run outside the sandbox").
denied_name(assertion, "a failed assertion prints a message and starts the debugger").
denied_name(format_predicate, "it changes how format/2 works for every later goal").
denied_name(thread_create, "a thread outlives the query's rollback").
denied_name(thread_create_in_pool, "a thread outlives the query's rollback").
denied_name(thread_signal, "it runs a goal in another thread").
denied_name(thread_send_message, "threads are not allowed in a query").
denied_name(thread_get_message, "threads are not allowed in a query").
denied_name(thread_join, "threads are not allowed in a query").
denied_name(thread_detach, "threads are not allowed in a query").
denied_name(thread_exit, "threads are not allowed in a query").
denied_name(first_solution, "it runs goals in threads").
denied_name(concurrent, "it runs goals in threads").
denied_name(concurrent_forall, "it runs goals in threads").
denied_name(concurrent_maplist, "it runs goals in threads").
denied_name(call_in_thread, "it runs goals in threads").
denied_name(nb_setval, "global variables outlive the query").
denied_name(b_setval, "global variables are not allowed in a query").
denied_name(nb_linkval, "global variables outlive the query").
denied_name(set_prolog_flag, "flags would change how later goals are read and run").
denied_name(create_prolog_flag, "flags would change how later goals are read and run").
denied_name(op, "operators would change how later goals are read").
denied_name(at_halt, "it runs a goal when the process ends, outside the sandbox").
denied_name(cancel_halt, "it changes how the process ends").
denied_name(prolog_listen, "event hooks run outside the sandbox").
denied_name(prolog_unlisten, "event hooks run outside the sandbox").
denied_name(put_attr, "attribute hooks run goals outside the sandbox").
denied_name(put_attrs, "attribute hooks run goals outside the sandbox").
denied_name(attr_unify_hook, "attribute hooks run goals outside the sandbox").
denied_name(portray_goal, "it calls a goal while printing").
denied_name(portray, "it calls a hook while printing").

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
           [Term, [quoted(true), numbervars(true), portray(false),
                   spacing(next_argument)]]).

%!  error_text(+Error, -Text:string) is det.
%
%   Text is a one-line description of the exception term Error, made without the
%   message system (whose translation of a term runs its `format/2` directives, `~@`
%   included, so printing a user's exception could run any goal).  ISO error terms get
%   their usual words; every other term, and every argument, is written with `~W`
%   (quoted, depth-limited, no portray hook, attributes ignored); control characters
%   become spaces.

error_text(Error, Text) :-
    (   catch(error_words(Error, Words), _, fail)
    ->  true
    ;   Words = "an exception that cannot be printed"
    ),
    one_line(Words, Text).

error_words(error(Formal, Context), Words) :- !,
    formal_words(Formal, Head),
    (   catch(context_words(Context, Tail), _, fail) -> true ; Tail = "" ),
    string_concat(Head, Tail, Words).
error_words(Term, Words) :-
    show("unhandled exception: ~W", [Term], Words).

formal_words(Var, Words) :- var(Var), !,
    Words = "unknown error".
formal_words(instantiation_error, "arguments are not sufficiently instantiated") :- !.
formal_words(uninstantiation_error(T), W) :- !, show("~W is not a fresh variable", [T], W).
formal_words(type_error(T, V), W) :- !, show("type error: ~W expected, found ~W", [T, V], W).
formal_words(domain_error(D, V), W) :- !, show("domain error: ~W expected, found ~W", [D, V], W).
formal_words(existence_error(procedure, PI), W) :- !, show("unknown procedure ~W", [PI], W).
formal_words(existence_error(K, V), W) :- !, show("~W ~W does not exist", [K, V], W).
formal_words(existence_error(K, V, In), W) :- !, show("~W ~W does not exist in ~W", [K, V, In], W).
formal_words(permission_error(A, T, C), W) :- !, show("no permission to ~W ~W ~W", [A, T, C], W).
formal_words(representation_error(R), W) :- !, show("cannot represent due to ~W", [R], W).
formal_words(evaluation_error(E), W) :- !, show("arithmetic: evaluation error: ~W", [E], W).
formal_words(resource_error(R), W) :- !, show("not enough resources: ~W", [R], W).
formal_words(syntax_error(S), W) :- !,
    syntax_words(S, Words),
    format(string(W), "syntax error: ~s", [Words]).
formal_words(Formal, W) :-
    show("unknown error term: ~W", [Formal], W).

context_words(Var, "") :- var(Var), !.
context_words(context(Culprit, Message), Words) :- !,
    (   var(Culprit) -> In = "" ; show(" (in ~W)", [Culprit], In) ),
    (   var(Message) -> Note = ""
    ;   ( atom(Message) ; string(Message) )
    ->  format(string(Note), ": ~w", [Message])
    ;   show(": ~W", [Message], Note)
    ),
    string_concat(In, Note, Words).
context_words(_, "").

%   syntax_words(+What, -Words): the reader's syntax error What in words
%   (operator_expected: "operator expected").
syntax_words(What, Words) :-
    atom(What), !,
    atomic_list_concat(Parts, '_', What),
    atomic_list_concat(Parts, ' ', Atom),
    atom_string(Atom, Words).
syntax_words(What, Words) :-
    show("~W", [What], Words).

%   show(+Format, +Terms, -Text): Format with each ~W given one of Terms and the safe
%   write options.
show(Format, Terms, Text) :-
    findall(Arg, ( member(T, Terms), member(Arg, [T, [quoted(true), max_depth(12), portray(false),
                                                     attributes(ignore), numbervars(false)]]) ),
            Args),
    format(string(Text), Format, Args).

one_line(Text0, Text) :-
    string_codes(Text0, Codes0),
    maplist(printable, Codes0, Codes),
    string_codes(Text, Codes).

printable(C0, C) :- ( C0 < 32 ; C0 =:= 127 ), !, C = 0' .
printable(C, C).
