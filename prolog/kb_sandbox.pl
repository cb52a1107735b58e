:- module(kb_sandbox,
          [ sandbox_main/0              % reads one request, answers it, halts
          ]).

/** <module> The child process that runs one user goal

`ita kb query`, `ita kb why` and each goal of `ita kb shell` start `swipl` on this
file in a process of its own (ita/logic/sandbox.py) behind the operating system's
walls (ita/logic/confine.py: bubblewrap's namespaces, a seccomp filter, rlimits, the
user nobody), and a wall-clock limit that the parent enforces by killing it.  The main
ITA process never runs a user goal.

The protocol is small.  The parent writes one JSON object on standard input:

    {"action": "query" | "why", "goal": Text, "engine_files": [Path...],
     "kb_files": [Path...], "bridge_modules": [Name...],
     "limit": N, "max_depth": N, "inference_limit": N}

The child loads the files (a fresh copy of the knowledge bases that dies with it, so
nothing the goal does can reach another query), writes `ready` and then one JSON reply
on standard output, and halts.  Before the goal runs, `user_output` and the current
output become standard error: whatever the goal prints goes there (the parent shows
it) and cannot be mistaken for the reply.  The time limit is the parent's (it kills
the process), so no alarm thread is needed: the child may run without the right to
start threads or processes.  The reply is one of

    {"status": "answers", "variables": [..], "rows": [[..]..], "truncated": Bool}
    {"status": "proof", "tree": Node}    Node = {"kind", "goal", "file", "line", "children"}
    {"status": "no_proof"}
    {"status": "refused" | "limit_exceeded" | "error" | "load_error", "reason": Text}

The goal itself runs through kb_query:with_user_goal/5: goal_hazard/2, then
library(sandbox), a temporary module, snapshot/1, and the time and inference limits.
*/

:- use_module(library(http/json)).
:- use_module(library(apply)).
:- use_module(library(lists)).
:- use_module(library(error)).
:- use_module(kb_query, [run_query/4, error_text/2]).
:- use_module(kb_explain, [explain_query/4]).
:- use_module(py_bridge, [load_source_files/2, file_module/2]).

%!  sandbox_main is det.
%
%   Read the request from standard input, load the knowledge bases, run the goal and
%   write the reply (see the module comment).  Always halts: 0 after a reply, 3 when
%   the request cannot be read.

sandbox_main :-
    set_stream(user_input, encoding(utf8)),
    set_stream(user_output, encoding(utf8)),
    set_stream(user_error, encoding(utf8)),
    (   catch(json_read_dict(user_input, Request, [value_string_as(string)]), _, fail),
        is_dict(Request)
    ->  true
    ;   format(user_error, "kb_sandbox: cannot read the request~n", []),
        halt(3)
    ),
    stream_property(Reply, alias(user_output)),
    set_stream(user_error, alias(user_output)),
    set_output(user_error),
    catch(answer(Request, Reply, Answer),
          Error,
          ( error_text(Error, Text),
            Answer = _{status: "error", reason: Text} )),
    json_write_dict(Reply, Answer, [width(0)]),
    nl(Reply),
    flush_output(Reply),
    halt(0).

answer(Request, Reply, Answer) :-
    atoms(Request.engine_files, EngineFiles),
    atoms(Request.kb_files, KbFiles),
    atoms(Request.bridge_modules, Bridge),
    append(EngineFiles, KbFiles, Files),
    load_source_files(Files, Diagnostics),
    (   member(diagnostic(error, File, Line, _, Message), Diagnostics)
    ->  format(string(Text), "~w:~w: ~w", [File, Line, Message]),
        Answer = _{status: "load_error", reason: Text}
    ;   modules(EngineFiles, EngineModules),
        modules(KbFiles, KbModules),
        exclude([M]>>memberchk(M, Bridge), EngineModules, Engines),
        format(Reply, "ready~n", []),
        flush_output(Reply),
        run(Request, KbModules, Engines, Answer)
    ).

run(Request, KbModules, Engines, Answer) :-
    Options = [ time_limit(none),
                inference_limit(Request.inference_limit)
              ],
    (   Request.action == "why"
    ->  explain_query(Request.goal, KbModules, [max_depth(Request.max_depth)|Options], Result)
    ;   append(KbModules, Engines, Modules),
        run_query(Request.goal, Modules, [limit(Request.limit)|Options], Result)
    ),
    result_dict(Result, Answer).

result_dict(answers(Names, Rows, Truncated), _{status: "answers", variables: Vars,
                                              rows: Rows, truncated: Truncated}) :- !,
    maplist(atom_string, Names, Vars).
result_dict(proof(Tree), _{status: "proof", tree: Node}) :- !,
    node_dict(Tree, Node).
result_dict(no_proof, _{status: "no_proof"}) :- !.
result_dict(Result, _{status: Status, reason: Reason}) :-
    Result =.. [Name, Reason0],
    atom_string(Name, Status),
    text_to_string(Reason0, Reason).

node_dict(node(Kind, Goal, File, Line, Children),
          _{kind: Kind, goal: Goal, file: File, line: Line, children: Dicts}) :-
    maplist(node_dict, Children, Dicts).

atoms(Strings, Atoms) :-
    maplist([S, A]>>atom_string(A, S), Strings, Atoms).

modules(Files, Modules) :-
    foldl(add_module, Files, Modules, []).

add_module(File, Modules0, Modules) :-
    (   file_module(File, Module)
    ->  Modules0 = [Module|Modules]
    ;   Modules0 = Modules
    ).
