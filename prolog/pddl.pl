:- module(pddl,
          [ read_pddl_domain/2,         % +File, -Domain
            read_pddl_problem/2,        % +File, -Problem
            pddl_task/3,                % +DomainFile, +ProblemFile, -Task
            solve_pddl/4,               % +DomainFile, +ProblemFile, +Options, -Result
            print_ipc_plan/1,           % +Actions
            solve_and_print/3,          % +DomainFile, +ProblemFile, +Options
            parse_sexprs/2,             % +Codes, -Expressions
            check_pddl/2,               % +DomainFile, +ProblemFile
            solve_cli/0                 % `swipl ... -- Domain Problem Time Depth Effort`
          ]).

/** <module> STRIPS PDDL into the planner's operators

Reads STRIPS PDDL (`:strips` and `:typing`, untyped and typed objects, `:constants`,
equality in preconditions) into the operator form of kb/operators.pl, so that the same
Task Planner solves the IPC problems:

  - a PDDL action becomes `static_operator(Action, Fields)` with preconditions, adders,
    deleters (PDDL's delete effects: STRIPS has no deductive operators), unary and n-ary
    constraints, no resources, and the action itself as its message pattern;
  - a precondition on a *static* predicate (one no action adds or deletes) is a
    constraint, unary or n-ary by its arity, answered by the problem's initial facts;
  - a parameter's type is the unary constraint `type(X, Type)`; an untyped parameter
    that no unary constraint covers gets `object(X)`, so every binding can be generated.

Symbols are lower-cased atoms; PDDL variables become Prolog variables.  The task also
carries a grounded relaxation (planner:relaxed_costs/3) that guides the planner's
hill climbing.
*/

:- use_module(library(apply)).
:- use_module(library(error)).
:- use_module(library(lists)).
:- use_module(library(option)).
:- use_module(library(pairs)).
:- use_module(library(readutil)).
:- use_module(library(assoc)).
:- use_module(library(time)).
:- use_module(planner).


                 /*******************************
                 *          S-EXPRESSIONS       *
                 *******************************/

%!  parse_sexprs(+Codes:list, -Expressions:list) is det.
%
%   Expressions are the s-expressions of the PDDL text Codes: a list is a Prolog list,
%   a symbol a lower-case atom, a `?name` variable the term `var(Name)`, a number a
%   number.  Comments (`;` to the end of the line) are skipped.
%
%   @error syntax_error(pddl(Message)) on unbalanced parentheses

parse_sexprs(Codes, Expressions) :-
    must_be(codes, Codes),
    tokens(Codes, Tokens),
    expressions(Tokens, Expressions).

tokens([], []).
tokens([C|Cs], Tokens) :-
    (   code_type(C, space)
    ->  tokens(Cs, Tokens)
    ;   C == 0';
    ->  skip_line(Cs, Rest),
        tokens(Rest, Tokens)
    ;   C == 0'(
    ->  Tokens = ['('|Ts],
        tokens(Cs, Ts)
    ;   C == 0')
    ->  Tokens = [')'|Ts],
        tokens(Cs, Ts)
    ;   symbol_codes([C|Cs], Sym, Rest),
        symbol_token(Sym, Token),
        Tokens = [Token|Ts],
        tokens(Rest, Ts)
    ).

skip_line([], []).
skip_line([C|Cs], Rest) :-
    (   C == 0'\n
    ->  Rest = Cs
    ;   skip_line(Cs, Rest)
    ).

symbol_codes([], [], []).
symbol_codes([C|Cs], Sym, Rest) :-
    (   ( code_type(C, space) ; C == 0'( ; C == 0') ; C == 0'; )
    ->  Sym = [],
        Rest = [C|Cs]
    ;   Sym = [C|Sym1],
        symbol_codes(Cs, Sym1, Rest)
    ).

symbol_token(Codes, Token) :-
    atom_codes(Atom0, Codes),
    downcase_atom(Atom0, Atom),
    (   sub_atom(Atom, 0, 1, _, ?)
    ->  sub_atom(Atom, 1, _, 0, Name),
        Token = sym(var(Name))
    ;   atom_number(Atom, Number)
    ->  Token = sym(Number)
    ;   Token = sym(Atom)
    ).

expressions([], []) :- !.
expressions(Tokens, [E|Es]) :-
    expression(Tokens, E, Rest),
    expressions(Rest, Es).

expression(['('|Ts], List, Rest) :- !,
    list_items(Ts, List, Rest).
expression([sym(S)|Ts], S, Ts) :- !.
expression([')'|_], _, _) :-
    syntax_error(pddl(unexpected_close_parenthesis)).

list_items([], _, _) :-
    syntax_error(pddl(missing_close_parenthesis)).
list_items([')'|Ts], [], Ts) :- !.
list_items(Ts, [E|Es], Rest) :-
    expression(Ts, E, Ts1),
    list_items(Ts1, Es, Rest).

read_sexprs(File, Expressions) :-
    must_be(atom, File),
    read_file_to_codes(File, Codes, []),
    parse_sexprs(Codes, Expressions).


                 /*******************************
                 *             DOMAIN           *
                 *******************************/

%!  read_pddl_domain(+File, -Domain) is det.
%
%   Domain is `pddl_domain(Name, Requirements, Types, Constants, Actions)`: Types a list
%   of Type-Supertype, Constants of Object-Type, Actions of
%   `action(Name, Parameters, Preconditions, Adders, Deleters)` with Parameters a list
%   of Var-Type (`object` when untyped) and the others lists of atoms (`=`(X, Y) and
%   `not(=(X, Y))` for equality).
%
%   @error domain_error(pddl_domain, File) if File holds no `(define (domain ...))`
%   @error domain_error(pddl_requirement, R) for requirements beyond STRIPS and typing

read_pddl_domain(File, pddl_domain(Name, Reqs, Types, Constants, Actions)) :-
    read_sexprs(File, Expressions),
    (   member([define, [domain, Name]|Sections], Expressions)
    ->  true
    ;   domain_error(pddl_domain, File)
    ),
    section(':requirements', Sections, Reqs),
    maplist(supported_requirement, Reqs),
    section(':types', Sections, TypeList),
    typed_list(TypeList, Types),
    section(':constants', Sections, ConstList),
    typed_list(ConstList, Constants),
    findall(Action, ( member([':action'|Body], Sections), action(Body, Action) ), Actions).

section(Key, Sections, Items) :-
    (   memberchk([Key|Items0], Sections)
    ->  Items = Items0
    ;   Items = []
    ).

supported_requirement(R) :-
    (   memberchk(R, [':strips', ':typing', ':equality', ':negative-preconditions'])
    ->  true
    ;   domain_error(pddl_requirement, R)
    ).

%   typed_list(+Items, -Pairs): `a b - t c` is [a-t, b-t, c-object].

typed_list([], []) :- !.
typed_list(Items, Pairs) :-
    append(Names, ['-', Type|Rest], Items),
    \+ memberchk('-', Names), !,
    findall(N-Type, member(N, Names), Typed),
    typed_list(Rest, More),
    append(Typed, More, Pairs).
typed_list(Items, Pairs) :-
    findall(N-object, member(N, Items), Pairs).

action([Name|Body], action(Name, Params, Pre, Add, Del)) :-
    keywords(Body, Pairs),
    (   memberchk(':parameters'-ParamList, Pairs) -> true ; ParamList = [] ),
    (   memberchk(':precondition'-PreExpr, Pairs) -> true ; PreExpr = [] ),
    (   memberchk(':effect'-EffExpr, Pairs) -> true ; EffExpr = [] ),
    typed_list(ParamList, Params),
    conjuncts(PreExpr, Pre),
    conjuncts(EffExpr, Effects),
    partition(positive, Effects, Add, Negative),
    maplist(negated, Negative, Del).

keywords([], []).
keywords([K, V|Rest], [K-V|Pairs]) :-
    keywords(Rest, Pairs).

conjuncts([], []) :- !.
conjuncts([and|Items], Atoms) :- !,
    maplist(conjuncts, Items, Lists),
    append(Lists, Atoms).
conjuncts(Atom, [Atom]).

positive(Atom) :-
    \+ Atom = [not, _].

negated([not, Atom], Atom).


                 /*******************************
                 *            PROBLEM           *
                 *******************************/

%!  read_pddl_problem(+File, -Problem) is det.
%
%   Problem is `pddl_problem(Name, DomainName, Objects, Init, Goals)`: Objects a list of
%   Object-Type, Init and Goals lists of ground atoms (as lists).
%
%   @error domain_error(pddl_problem, File) if File holds no `(define (problem ...))`
%   @error domain_error(strips_goal, Goal) for a goal that is not a conjunction of atoms

read_pddl_problem(File, pddl_problem(Name, DomainName, Objects, Init, Goals)) :-
    read_sexprs(File, Expressions),
    (   member([define, [problem, Name]|Sections], Expressions)
    ->  true
    ;   domain_error(pddl_problem, File)
    ),
    (   memberchk([':domain', DomainName], Sections) -> true ; DomainName = unknown ),
    section(':objects', Sections, ObjList),
    typed_list(ObjList, Objects),
    section(':init', Sections, Init),
    section(':goal', Sections, GoalList),
    (   GoalList = [GoalExpr]
    ->  conjuncts(GoalExpr, Goals)
    ;   Goals = []
    ),
    forall(member(G, Goals), ( G = [not|_] -> domain_error(strips_goal, G) ; true )).


                 /*******************************
                 *              TASK            *
                 *******************************/

%!  pddl_task(+DomainFile, +ProblemFile, -Task) is det.
%
%   Task is `task(Domain, State, Goals)`: Domain compiled for the planner (operators,
%   static facts, grounded relaxation), State the dynamic initial facts and Goals the
%   goal facts, as Prolog terms.

pddl_task(DomainFile, ProblemFile, Task) :-
    once(task(DomainFile, ProblemFile, Task)).

task(DomainFile, ProblemFile, task(Domain, State, Goals)) :-
    check_pddl(DomainFile, ProblemFile),
    read_pddl_domain(DomainFile, pddl_domain(_, _, Types, Constants, Actions)),
    read_pddl_problem(ProblemFile, pddl_problem(_, _, Objects0, Init0, Goals0)),
    append(Constants, Objects0, Objects),
    maplist(atom_term, Init0, Init),
    maplist(atom_term, Goals0, Goals),
    dynamic_predicates(Actions, Dynamic),
    partition(is_dynamic(Dynamic), Init, State0, Static0),
    type_facts(Objects, Types, TypeFacts),
    append(Static0, TypeFacts, StaticFacts),
    maplist(operator(Dynamic), Actions, Operators),
    compile_domain(operators(Operators, [], [facts(StaticFacts)]), Domain0),
    sort(State0, State),
    relaxation(Domain0, Operators, Objects, State, Relaxed),
    compile_domain(operators(Operators, [], [facts(StaticFacts), relaxed(Relaxed)]), Domain).

atom_term([Name|Args], Term) :- !,
    maplist(arg_term, Args, Args1),
    Term =.. [Name|Args1].
atom_term(Name, Name).

arg_term(var(_), _) :- !,
    domain_error(ground_atom, var).
arg_term(A, A).

dynamic_predicates(Actions, Dynamic) :-
    findall(Name/Arity,
            ( member(action(_, _, _, Add, Del), Actions),
              ( member(A, Add) ; member(A, Del) ),
              atom_key(A, Name, Arity)
            ),
            Keys),
    sort(Keys, Dynamic).

atom_key([Name|Args], Name, Arity) :- !,
    length(Args, Arity).
atom_key(Name, Name, 0).

is_dynamic(Dynamic, Fact) :-
    functor(Fact, Name, Arity),
    memberchk(Name/Arity, Dynamic).

type_facts(Objects, Types, Facts) :-
    findall(F, ( member(O-T, Objects),
                 ( F = object(O)
                 ; supertype(T, Types, S), F = type(O, S)
                 )
               ), Facts0),
    sort(Facts0, Facts).

supertype(T, _, T).
supertype(T, Types, S) :-
    memberchk(T-Parent, Types),
    Parent \== T,
    supertype(Parent, Types, S).

%   operator(+Dynamic, +Action, -Operator)
%
%   The planner's static_operator/2 term of a PDDL action.

operator(Dynamic, action(Name, Params, Pre0, Add0, Del0),
         static_operator(Action, [ preconditions(Pre), adders(Add), deleters(Del),
                                   unary_constraints(Unary), n_ary_constraints(Nary),
                                   resources([]), message_pattern(Action),
                                   command_stream(pddl), reply_pattern(done),
                                   result_pattern(Action) ])) :-
    pairs_keys(Params, ParamVars),
    maplist(var_binding, ParamVars, Bindings),
    maplist(bind_atom(Bindings), Pre0, Pre1),
    maplist(bind_atom(Bindings), Add0, Add),
    maplist(bind_atom(Bindings), Del0, Del),
    pairs_values(Bindings, Vars),
    Action =.. [Name|Vars],
    split_preconditions(Pre1, Dynamic, Pre, Static, Equalities),
    partition(unary, Static, StaticUnary, StaticNary),
    maplist(param_type(Bindings), Params, TypeConstraints0),
    exclude(==(none), TypeConstraints0, TypeConstraints),
    append(TypeConstraints, StaticUnary, Unary0),
    covered_objects(Vars, Unary0, Unary),
    append(StaticNary, Equalities, Nary).

var_binding(var(Name), Name-_).

bind_atom(Bindings, [not, Atom], not(Term)) :- !,
    bind_atom(Bindings, Atom, Term).
bind_atom(Bindings, [Name|Args], Term) :- !,
    maplist(bind_arg(Bindings), Args, Args1),
    Term =.. [Name|Args1].
bind_atom(_, Name, Name).

bind_arg(Bindings, var(Name), Var) :- !,
    (   memberchk(Name-Var, Bindings)
    ->  true
    ;   existence_error(pddl_parameter, Name)
    ).
bind_arg(_, Constant, Constant).

split_preconditions([], _, [], [], []).
split_preconditions([P|Ps], Dynamic, Pre, Static, Eq) :-
    (   P = (X = Y)
    ->  Eq = [X == Y|Eq1], Pre = Pre1, Static = Static1
    ;   P = not(X = Y)
    ->  Eq = [X \== Y|Eq1], Pre = Pre1, Static = Static1
    ;   P = not(_)
    ->  domain_error(strips_precondition, P)
    ;   is_dynamic(Dynamic, P)
    ->  Pre = [P|Pre1], Static = Static1, Eq = Eq1
    ;   Static = [P|Static1], Pre = Pre1, Eq = Eq1
    ),
    split_preconditions(Ps, Dynamic, Pre1, Static1, Eq1).

unary(Atom) :-
    compound(Atom),
    functor(Atom, _, 1).

param_type(Bindings, var(Name)-Type, Constraint) :-
    memberchk(Name-Var, Bindings),
    (   Type == object
    ->  Constraint = none
    ;   Constraint = type(Var, Type)
    ).

covered_objects(Vars, Unary0, Unary) :-
    term_variables(Unary0, Covered),
    exclude(in_vars(Covered), Vars, Uncovered),
    maplist(object_constraint, Uncovered, ObjectConstraints),
    append(Unary0, ObjectConstraints, Unary).

in_vars(Vars, V) :-
    member(W, Vars), W == V, !.

object_constraint(V, object(V)).


                 /*******************************
                 *           RELAXATION         *
                 *******************************/

%   relaxation(+Domain, +Operators, +Objects, +State, -Relaxed)
%
%   Ground every operator whose constraints hold, keep the actions reachable from
%   State when delete lists are ignored, and number their facts.

relaxation(Domain, Operators, _Objects, State, Relaxed) :-
    findall(Pre-Add, ground_action(Domain, Operators, Pre, Add), All),
    table(All, State, Relaxed0),
    relaxed_costs(Relaxed0, State, costs(_, Costs)),
    include(reachable(Relaxed0, Costs), All, Reachable),
    table(Reachable, State, Relaxed).

ground_action(Domain, Operators, Pre, Add) :-
    member(static_operator(Action, _), Operators),
    domain_operator(Domain, Action, op(Action, Pre, Add, _, Unary, Nary, _)),
    constraints_hold(Domain, [], Unary),
    constraints_hold(Domain, [], Nary),
    ground(Pre-Add).

reachable(relaxed(Index, _, _, _, _, _), Costs, Pre-_) :-
    forall(member(P, Pre),
           ( get_assoc(P, Index, Id), arg(Id, Costs, C), C < 1000000 )).

table(Actions, State, relaxed(Index, NFacts, PreT, AddT, PreOfT, Free)) :-
    findall(F, ( member(Pre-Add, Actions), ( member(F, Pre) ; member(F, Add) ) ), Fs0),
    append(State, Fs0, Fs1),
    sort(Fs1, Facts),
    length(Facts, NFacts),
    numlist_pairs(Facts, 1, Pairs),
    list_to_assoc(Pairs, Index),
    maplist(ids(Index), Actions, PreIds, AddIds),
    PreT =.. [a|PreIds],
    AddT =.. [a|AddIds],
    length(Actions, NActs),
    findall(F-A, ( nth1(A, PreIds, Ps), member(F, Ps) ), FA0),
    keysort(FA0, FA),
    group_pairs_by_key(FA, Groups),
    numlist(1, NFacts, AllFacts),
    maplist(users(Groups), AllFacts, Users),
    PreOfT =.. [a|Users],
    findall(A, ( between(1, NActs, A), nth1(A, PreIds, []) ), Free).

numlist_pairs([], _, []).
numlist_pairs([F|Fs], N, [F-N|Ps]) :-
    N1 is N + 1,
    numlist_pairs(Fs, N1, Ps).

ids(Index, Pre-Add, PreIds, AddIds) :-
    maplist(fact_id(Index), Pre, PreIds0),
    sort(PreIds0, PreIds),
    maplist(fact_id(Index), Add, AddIds).

fact_id(Index, F, Id) :-
    get_assoc(F, Index, Id).

users(Groups, F, Users) :-
    (   memberchk(F-Users0, Groups)
    ->  Users = Users0
    ;   Users = []
    ).


                 /*******************************
                 *            SOLVING           *
                 *******************************/

%!  solve_pddl(+DomainFile, +ProblemFile, +Options, -Result) is det.
%
%   Result is `plan(Actions)` (a sequence of ground actions in execution order) or
%   `no_plan(Reason)`.  Options are those of planner:plan_result/4 (max_effort,
%   max_depth, rounds) and time_limit(Seconds) (default 60), after which Reason is
%   `time_limit_exceeded(Seconds)`.

solve_pddl(DomainFile, ProblemFile, Options, Result) :-
    must_be(list, Options),
    option(time_limit(Limit), Options, 60),
    catch(call_with_time_limit(Limit, task_and_plan(DomainFile, ProblemFile, Options, R0)),
          time_limit_exceeded,
          R0 = no_plan(time_limit_exceeded(Limit))),
    (   R0 = plan(Steps)
    ->  findall(A, member(step(_, A, _), Steps), Actions),
        Result = plan(Actions)
    ;   Result = R0
    ).

%   The task is built inside the time limit too: grounding a large problem takes long.
task_and_plan(DomainFile, ProblemFile, Options, R0) :-
    once(pddl_task(DomainFile, ProblemFile, task(Domain, State, Goals))),
    merge_options([domain(Domain)], Options, PlanOptions0),
    merge_options(PlanOptions0, [max_effort(200000), max_depth(60)], PlanOptions),
    plan_result(Goals, State, PlanOptions, R0).

%!  solve_cli is det.
%
%   The entry of `ita pddl solve`, run in a child process that the parent kills at its
%   time limit: the last five command-line arguments are DomainFile, ProblemFile,
%   Seconds, MaxDepth and MaxEffort.  Writes one line, the result of solve_pddl/4 or
%   `error(Message)`, quoted and in functional notation, and halts.

solve_cli :-
    current_prolog_flag(argv, Argv),
    append(_, [Domain, Problem, TimeText, DepthText, EffortText], Argv), !,
    atom_number(TimeText, Time),
    atom_number(DepthText, Depth),
    atom_number(EffortText, Effort),
    catch(solve_pddl(Domain, Problem, [time_limit(Time), max_depth(Depth), max_effort(Effort)], Result),
          Error,
          ( message_to_codes(Error, Codes), string_codes(Text, Codes), Result = error(Text) )),
    write_term(Result, [quoted(true), ignore_ops(true), brace_terms(false), numbervars(false)]),
    nl,
    halt(0).
solve_cli :-
    format(user_error, "usage: solve_cli Domain Problem Seconds MaxDepth MaxEffort~n", []),
    halt(2).

message_to_codes(Error, Codes) :-
    (   Error = error(Formal, _) -> Plain = error(Formal, _) ; Plain = Error ),
    (   catch('$messages':translate_message(Plain, Lines, []), _, fail)
    ->  with_output_to(codes(Codes0), print_message_lines(current_output, '', Lines)),
        maplist([C0, C]>>( C0 == 0'\n -> C = 0'\s ; C = C0 ), Codes0, Codes)
    ;   format(codes(Codes), "~q", [Error])
    ).

%!  print_ipc_plan(+Actions:list) is det.
%
%   Print Actions in the IPC plan format, one `(name arg ...)` per line.

print_ipc_plan(Actions) :-
    must_be(list, Actions),
    forall(member(A, Actions),
           ( A =.. [Name|Args],
             atomic_list_concat([Name|Args], ' ', Text),
             format('(~w)~n', [Text]) )).

%!  solve_and_print(+DomainFile, +ProblemFile, +Options) is semidet.
%
%   Solve the problem and print the plan in the IPC format, then a comment line with
%   its length and CPU time; print `; no plan: Reason` and fail when there is none.

solve_and_print(DomainFile, ProblemFile, Options) :-
    statistics(cputime, T0),
    solve_pddl(DomainFile, ProblemFile, Options, Result),
    statistics(cputime, T1),
    Time is T1 - T0,
    (   Result = plan(Actions)
    ->  print_ipc_plan(Actions),
        length(Actions, Length),
        format('; length ~d, ~3f s~n', [Length, Time])
    ;   Result = no_plan(Reason),
        format('; no plan: ~q, ~3f s~n', [Reason, Time]),
        fail
    ).


                 /*******************************
                 *            CHECKS            *
                 *******************************/

:- multifile prolog:error_message//1.

prolog:error_message(pddl(Message)) -->
    [ '~w'-[Message] ].

%!  check_pddl(+DomainFile, +ProblemFile) is det.
%
%   Check a problem against its domain and the domain against its requirements, for
%   what the reader would otherwise accept silently: the problem's `:domain` must name
%   the domain, the problem must have a `:goal`, types (`- type`) need `:typing`,
%   effects must be STRIPS (no `when`, `forall`, `exists`), preconditions conjunctions
%   of literals (no `or`, `imply`, `forall`, `exists`), and when the domain declares
%   `:predicates`, every atom of an action, `:init` or `:goal` must use one of them
%   with its arity.  Files without a define are left to the reader's own errors.
%
%   @error pddl(Message) with the offending symbol as the last word of Message

check_pddl(DomainFile, ProblemFile) :-
    read_sexprs(DomainFile, DomainExprs),
    read_sexprs(ProblemFile, ProblemExprs),
    (   member([define, [domain, DomainName]|DS], DomainExprs),
        member([define, [problem, _]|PS], ProblemExprs)
    ->  check_sections(DomainName, DS, PS)
    ;   true
    ).

check_sections(DomainName, DS, PS) :-
    (   memberchk([':domain', Named], PS), Named \== DomainName
    ->  pddl_error("wrong domain: the domain file defines ~w, the problem's :domain is ~w",
                   [DomainName, Named])
    ;   true
    ),
    (   memberchk([':goal'|_], PS)
    ->  true
    ;   pddl_error("the problem has no :goal section; problem", [])
    ),
    section(':requirements', DS, Reqs),
    (   memberchk(':typing', Reqs)
    ->  true
    ;   typed_somewhere(DS, PS, Where)
    ->  pddl_error("types (\"- type\") need the :typing requirement; typed: ~w", [Where])
    ;   true
    ),
    forall(member([':action', Name|Body], DS), check_action(Name, Body)),
    (   memberchk([':predicates'|Decls], DS)
    ->  declared(Decls, Keys),
        forall(used_atom(DS, PS, Atom), check_declared(Keys, Atom))
    ;   true
    ).

typed_somewhere(DS, PS, Where) :-
    (   member(Key, [':types', ':constants']), section(Key, DS, Items)
    ;   section(':objects', PS, Items)
    ;   member([':action'|Body], DS), keywords_of(Body, Pairs), memberchk(':parameters'-Items, Pairs)
    ),
    append(_, ['-', Where|_], Items), !.

keywords_of([_Name|Body], Pairs) :-
    catch(keywords(Body, Pairs), _, Pairs = []), !.
keywords_of(_, []).

check_action(Name, Body) :-
    (   catch(keywords(Body, Pairs), _, fail) -> true ; Pairs = [] ),
    (   memberchk(':effect'-Effect, Pairs),
        connective(Effect, Connective),
        memberchk(Connective, [when, forall, exists])
    ->  pddl_error("conditional or quantified effects are not STRIPS; action ~w uses ~w",
                   [Name, Connective])
    ;   true
    ),
    (   memberchk(':precondition'-Pre, Pairs),
        connective(Pre, Connective2),
        memberchk(Connective2, [or, imply, forall, exists])
    ->  pddl_error("only conjunctions of literals are STRIPS preconditions; action ~w uses ~w",
                   [Name, Connective2])
    ;   true
    ).

%   connective(+Expr, -Name): a connective (and, not, when...) used anywhere in Expr.
connective([Head|Args], Name) :-
    atom(Head),
    memberchk(Head, [and, not, or, imply, when, forall, exists]),
    (   Name = Head
    ;   member(Arg, Args), is_list(Arg), connective(Arg, Name)
    ).

declared(Decls, Keys) :-
    findall(Name/Arity,
            ( member([Name|Params], Decls),
              atom(Name),
              typed_list(Params, Typed),
              length(Typed, Arity)
            ),
            Keys).

used_atom(DS, PS, Atom) :-
    (   member([':action', _|Body], DS),
        catch(keywords(Body, Pairs), _, fail),
        member(Key-Expr, Pairs),
        memberchk(Key, [':precondition', ':effect']),
        expr_atom(Expr, Atom)
    ;   section(':init', PS, Init), member(Atom, Init)
    ;   section(':goal', PS, Goal), member(Expr, Goal), expr_atom(Expr, Atom)
    ).

expr_atom([Head|Args], Atom) :-
    atom(Head),
    memberchk(Head, [and, not, or, imply, when]), !,
    member(Arg, Args),
    expr_atom(Arg, Atom).
expr_atom([Head, _Vars, Body], Atom) :-
    memberchk(Head, [forall, exists]), !,
    expr_atom(Body, Atom).
expr_atom([], _) :- !, fail.
expr_atom(Atom, Atom).

check_declared(Keys, Atom) :-
    (   Atom = [Name|Args] -> length(Args, Arity) ; Name = Atom, Arity = 0 ),
    (   Name == (=)
    ->  true
    ;   memberchk(Name/Arity, Keys)
    ->  true
    ;   memberchk(Name/Declared, Keys)
    ->  pddl_error("~w has ~d arguments here but ~d in :predicates; predicate ~w",
                   [Name, Arity, Declared, Name])
    ;   pddl_error("predicate not declared in :predicates: ~w", [Name])
    ).

pddl_error(Format, Args) :-
    format(string(Message), Format, Args),
    throw(error(pddl(Message), _)).
