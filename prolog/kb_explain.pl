:- module(kb_explain,
          [ explain_query/4,            % +Text, +KbModules, +Options, -Result
            prove/4                     % :Goal, +KbModules, +MaxDepth, -Proofs
          ]).

/** <module> Why does a goal hold? Proof trees over the knowledge bases

A small meta-interpreter that proves a goal the way Prolog does and records how: each
call of a predicate defined by clauses of a knowledge-base module becomes a node
(`rule` or `fact`, with the file and line of the clause used) whose children prove the
clause body.  Calls of anything else (built-ins, libraries, engines) are proved by
calling them and become leaves (`builtin`); `\+ G` becomes a `negation` leaf.  Below
the depth limit goals are called directly and shown as `depth_limit` leaves.

A cut at the top level of a clause body commits to that clause, as in Prolog; a cut
nested inside a disjunction or if-then-else of a body is treated as `true`.
*/

:- use_module(library(error)).
:- use_module(library(lists)).
:- use_module(library(apply)).
:- use_module(library(option)).
:- use_module(kb_query, [with_user_goal/5, term_text/2]).

:- meta_predicate prove(:, +, +, -).

%!  explain_query(+Text:text, +KbModules:list(atom), +Options:list, -Result) is det.
%
%   Prove the user goal Text, with the safety of kb_query:with_user_goal/5 (whose
%   Options it accepts, and `max_depth(D)`, default 30), expanding the predicates of
%   KbModules.  Result is `proof(Tree)` for the first solution, `no_proof` when the goal
%   fails, or a `refused/1`, `limit_exceeded/1` or `error/1` term.  Tree is
%   `node(Kind, GoalText, File, Line, Children)` with Kind `query` at the root (the
%   goal as solved), File `''` and Line 0 where there is no clause.

explain_query(Text, KbModules, Options, Result) :-
    must_be(list, Options),
    option(max_depth(Depth), Options, 30),
    must_be(nonneg, Depth),
    with_user_goal(Text, KbModules, Options,
                   kb_explain:explain_action(KbModules, Depth), Result).

:- public explain_action/6.

explain_action(KbModules, Depth, Module, Goal, _Bindings, Result) :-
    (   prove(Module:Goal, KbModules, Depth, Proofs)
    ->  copy_term(Goal-Proofs, GoalCopy-ProofsCopy, _),
        term_variables(GoalCopy-ProofsCopy, Vars),
        name_vars(Vars, 1),
        term_text(GoalCopy, GoalText),
        maplist(node_text, ProofsCopy, Children),
        Result = proof(node(query, GoalText, '', 0, Children))
    ;   Result = no_proof
    ).

name_vars([], _).
name_vars([V|Vs], N) :-
    format(atom(Name), "_~d", [N]),
    V = '$VAR'(Name),
    N1 is N + 1,
    name_vars(Vs, N1).

node_text(proof(Kind, Goal, File, Line, Proofs),
          node(Kind, Text, File, Line, Children)) :-
    term_text(Goal, Text),
    maplist(node_text, Proofs, Children).

%!  prove(:Goal, +KbModules:list(atom), +MaxDepth:nonneg, -Proofs:list) is nondet.
%
%   Prove Goal, a conjunction in the context of its module, and give one proof term
%   `proof(Kind, Goal, File, Line, Proofs)` per goal of the conjunction proved.
%   Predicates of KbModules are expanded clause by clause up to MaxDepth levels.

prove(Module:Goal, KbModules, MaxDepth, Proofs) :-
    must_be(list(atom), KbModules),
    must_be(nonneg, MaxDepth),
    prove_body(Goal, Module, ctx(KbModules, MaxDepth), Proofs).

prove_body(Goal, _, _, _) :-
    var(Goal), !,
    instantiation_error(Goal).
prove_body(true, _, _, []) :- !.
prove_body(!, _, _, []) :- !.
prove_body((A, B), M, Ctx, Proofs) :- !,
    prove_body(A, M, Ctx, PA),
    prove_body(B, M, Ctx, PB),
    append(PA, PB, Proofs).
prove_body((If -> Then ; Else), M, Ctx, Proofs) :- !,
    (   prove_body(If, M, Ctx, PI)
    ->  prove_body(Then, M, Ctx, PT),
        append(PI, PT, Proofs)
    ;   prove_body(Else, M, Ctx, Proofs)
    ).
prove_body((If *-> Then ; Else), M, Ctx, Proofs) :- !,
    (   prove_body(If, M, Ctx, PI)
    *-> prove_body(Then, M, Ctx, PT),
        append(PI, PT, Proofs)
    ;   prove_body(Else, M, Ctx, Proofs)
    ).
prove_body((A ; B), M, Ctx, Proofs) :- !,
    (   prove_body(A, M, Ctx, Proofs)
    ;   prove_body(B, M, Ctx, Proofs)
    ).
prove_body((If -> Then), M, Ctx, Proofs) :- !,
    (   prove_body(If, M, Ctx, PI)
    ->  prove_body(Then, M, Ctx, PT),
        append(PI, PT, Proofs)
    ).
prove_body(\+ Goal, M, _, [proof(negation, \+ Goal, '', 0, [])]) :- !,
    \+ call(M:Goal).
prove_body(M1:Goal, _, Ctx, Proofs) :- !,
    prove_body(Goal, M1, Ctx, Proofs).
prove_body(Goal, M, Ctx, [Proof]) :-
    prove_goal(Goal, M, Ctx, Proof).

prove_goal(Goal, M, ctx(KbModules, Depth), Proof) :-
    expandable(Goal, M, KbModules, Definer), !,
    (   Depth =< 0
    ->  call(M:Goal),
        Proof = proof(depth_limit, Goal, '', 0, [])
    ;   Depth1 is Depth - 1,
        prove_clause(Goal, Definer, ctx(KbModules, Depth1), Proof)
    ).
prove_goal(Goal, M, _, proof(builtin, Goal, '', 0, [])) :-
    call(M:Goal).

prove_clause(Goal, Module, Ctx, proof(Kind, Goal, File, Line, Proofs)) :-
    clause(Module:Goal, Body0, Ref),
    clause_location(Ref, File, Line),
    (   Body0 == true -> Kind = fact ; Kind = rule ),
    body_module(Body0, Module, Body, BodyModule),
    split_at_cut(Body, Before, After),
    (   After == no_cut
    ->  prove_body(Body, BodyModule, Ctx, Proofs)
    ;   prove_body(Before, BodyModule, Ctx, P1),
        !,
        prove_body(After, BodyModule, Ctx, P2),
        append(P1, P2, Proofs)
    ).

%   A body may come back qualified with the module it was compiled in.
body_module(Body0, Module0, Body, Module) :-
    (   nonvar(Body0), Body0 = M:B, atom(M)
    ->  body_module(B, M, Body, Module)
    ;   Body = Body0,
        Module = Module0
    ).

clause_location(Ref, File, Line) :-
    clause_property(Ref, file(File)),
    clause_property(Ref, line_count(Line)), !.
clause_location(_, '', 0).

%   split_at_cut(+Body, -Before, -After): After is `no_cut` when the top-level
%   conjunction of Body has no cut.
split_at_cut(Body, Before, After) :-
    conj_list(Body, Goals),
    (   append(BeforeList, [!|AfterList], Goals)
    ->  list_conj(BeforeList, Before),
        list_conj(AfterList, After)
    ;   Before = Body,
        After = no_cut
    ).

conj_list(Var, [Var]) :- var(Var), !.
conj_list((A, B), Goals) :- !,
    conj_list(A, GA),
    conj_list(B, GB),
    append(GA, GB, Goals).
conj_list(Goal, [Goal]).

list_conj([], true).
list_conj([G], G) :- !.
list_conj([G|Gs], (G, C)) :- list_conj(Gs, C).

expandable(Goal, M, KbModules, Definer) :-
    callable(Goal),
    (   predicate_property(M:Goal, imported_from(Definer0))
    ->  Definer = Definer0
    ;   Definer = M
    ),
    memberchk(Definer, KbModules),
    predicate_property(Definer:Goal, defined),
    \+ predicate_property(Definer:Goal, foreign),
    \+ predicate_property(Definer:Goal, tabled).
