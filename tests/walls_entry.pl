:- module(kb_sandbox,
          [ sandbox_main/0              % reads one request, runs its goal bare, halts
          ]).

/** <module> A test fixture: the query child with no Prolog check at all

tests/test_kb_walls.py starts this file in place of prolog/kb_sandbox.pl, behind the
same operating-system walls (ita/logic/confine.py).  It has no goal_hazard/2 and no
library(sandbox): the goal of the request is called as it is, so whatever harm it does
is stopped by the walls or not at all.  It is never part of the product.

It answers the protocol of kb_sandbox.pl: `ready`, then one JSON reply whose single row
is the goal's outcome (`true`, `false` or `error: E`, E written with ~q).
*/

:- use_module(library(http/json)).

sandbox_main :-
    set_stream(user_input, encoding(utf8)),
    set_stream(user_output, encoding(utf8)),
    json_read_dict(user_input, Request, [value_string_as(string)]),
    stream_property(Reply, alias(user_output)),
    format(Reply, "ready~n", []),
    flush_output(Reply),
    set_stream(user_error, alias(user_output)),
    set_output(user_error),
    term_string(Goal, Request.goal),
    (   catch(Goal, Error, true)
    ->  (   var(Error) -> Outcome = "true" ; format(string(Outcome), "error: ~q", [Error]) )
    ;   Outcome = "false"
    ),
    json_write_dict(Reply, _{status: "answers", variables: ["Outcome"], rows: [[Outcome]],
                             truncated: false}, [width(0)]),
    nl(Reply),
    flush_output(Reply),
    halt(0).
