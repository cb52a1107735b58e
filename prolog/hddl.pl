:- module(hddl,
          [ read_hddl/3,                % +DomainFile, +ProblemFile, -Task
            hddl_solve/4,               % +DomainFile, +ProblemFile, +Options, -Result
            parse_hddl/3,               % +File, +Codes, -Expressions
            solve_cli/0                 % `swipl ... -- Domain Problem Seconds MaxNodes`
          ]).

/** <module> Total-order HDDL into the HTN planner

Reads the total-order HDDL of the IPC 2020 (Höller et al., AAAI 2020) into the domain
form of prolog/htn.pl: a temporary module with `operator/4` and `method/4` facts, the
initial state as facts, the initial task network and the state goal.

Supported: `:typing` (a type hierarchy, `either` types), `:negative-preconditions`,
`:equality`, `:method-preconditions`, `:universal-preconditions` and the other
quantified, disjunctive and implied preconditions (`forall`, `exists`, `or`,
`imply`), `:ordered-subtasks` / `:ordered-tasks`, and `:subtasks` / `:tasks` whose
`:ordering` is total, method `:constraints` (read as preconditions), domain
`:constants`, a problem's `:htn` (with `:parameters`), `:init` and `:goal`.

Refused with an error naming the feature, the file and the line: conditional effects
(`when`), quantified effects (`forall` in an effect), an `:ordering` that leaves two
subtasks unordered (partial order), numeric fluents and action costs (`:functions`,
`:metric`, `:numeric-fluents`, `:action-costs`), durative actions, derived predicates,
problem `:constraints`, and any requirement not named above.

Symbols are lower-cased atoms; types are the static facts `'$type'(Type, Object)`,
an object being of its declared type, that type's ancestors and `object`.  The type
of each parameter is checked by a literal placed after the precondition literal that
binds it; a method parameter that no precondition binds is typed by a lazy literal
(htn.pl), so it stays a variable until a subtask's action binds it.

Errors are `error(hddl(File, Line, Message), _)`.
*/

:- use_module(library(apply)).
:- use_module(library(assoc)).
:- use_module(library(error)).
:- use_module(library(lists)).
:- use_module(library(option)).
:- use_module(library(pairs)).
:- use_module(library(readutil)).
:- use_module(htn).

:- multifile prolog:error_message//1.

prolog:error_message(hddl(File, Line, Message)) -->
    [ '~w:~w: ~w'-[File, Line, Message] ].


                 /*******************************
                 *          S-EXPRESSIONS       *
                 *******************************/

%!  parse_hddl(+File, +Codes:list, -Expressions:list) is det.
%
%   Expressions are the s-expressions of the HDDL text Codes: a parenthesised list is
%   `l(Line, Items)`, a symbol a lower-case atom, a `?name` variable `var(Name)`.
%   Comments (`;` to the end of the line) are skipped.  (pddl:parse_sexprs/2 keeps no
%   line numbers, which the errors here need.)
%
%   @error hddl(File, Line, Message) for a parenthesis that does not balance

parse_hddl(File, Codes, Expressions) :-
    must_be(codes, Codes),
    tokens(Codes, 1, Tokens),
    catch(expressions(Tokens, File, Expressions),
          error(hddl(File, Line0, Message), Context),
          (   sub_string(Message, _, _, _, "never closed")
          ->  unclosed_line(Tokens, Line),
              throw(error(hddl(File, Line, Message), Context))
          ;   throw(error(hddl(File, Line0, Message), Context))
          )).

%   unclosed_line(+Tokens, -Line): the line of the parenthesis that is never closed,
%   as well as it can be told: a keyword list (a section, :method, :action, :task: its
%   first symbol starts with a colon; they do not nest) still open where the next one
%   begins; else the innermost list open at the end.
unclosed_line(Tokens, Line) :-
    unclosed(Tokens, [], Line).

unclosed([], Stack, Line) :-
    (   Stack = [open(Line, _)|_] -> true ; Line = 1 ).
unclosed([T|Ts], Stack, Line) :-
    (   T = open(L), Ts = [sym(S, _)|_], atom(S), sub_atom(S, 0, 1, _, :)
    ->  (   memberchk(open(Open, keyword), Stack)
        ->  Line = Open
        ;   unclosed(Ts, [open(L, keyword)|Stack], Line)
        )
    ;   T = open(L)
    ->  unclosed(Ts, [open(L, list)|Stack], Line)
    ;   T = close(_)
    ->  (   Stack = [_|Stack1] -> true ; Stack1 = [] ),
        unclosed(Ts, Stack1, Line)
    ;   unclosed(Ts, Stack, Line)
    ).

tokens([], _, []).
tokens([C|Cs], Line, Tokens) :-
    (   C == 0'\n
    ->  Line1 is Line + 1,
        tokens(Cs, Line1, Tokens)
    ;   code_type(C, space)
    ->  tokens(Cs, Line, Tokens)
    ;   C == 0';
    ->  skip_line(Cs, Rest),
        tokens([0'\n|Rest], Line, Tokens)
    ;   C == 0'(
    ->  Tokens = [open(Line)|Ts],
        tokens(Cs, Line, Ts)
    ;   C == 0')
    ->  Tokens = [close(Line)|Ts],
        tokens(Cs, Line, Ts)
    ;   symbol_codes([C|Cs], Sym, Rest),
        symbol_token(Sym, Token),
        Tokens = [sym(Token, Line)|Ts],
        tokens(Rest, Line, Ts)
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
        Token = var(Name)
    ;   Token = Atom
    ).

expressions([], _, []) :- !.
expressions(Tokens, File, [E|Es]) :-
    expression(Tokens, File, E, Rest),
    expressions(Rest, File, Es).

expression([open(Line)|Ts], File, l(Line, Items), Rest) :- !,
    list_items(Ts, File, Line, Items, Rest).
expression([sym(S, _)|Ts], _, S, Ts) :- !.
expression([close(Line)|_], File, _, _) :-
    hddl_error(File, Line, "unbalanced parentheses: unexpected ')'", []).

list_items([], File, Line, _, _) :-
    hddl_error(File, Line, "unbalanced parentheses: '(' is never closed", []).
list_items([close(_)|Ts], _, _, [], Ts) :- !.
list_items(Ts, File, Line, [E|Es], Rest) :-
    expression(Ts, File, E, Ts1),
    list_items(Ts1, File, Line, Es, Rest).

hddl_error(File, Line, Format, Args) :-
    format(string(Message), Format, Args),
    throw(error(hddl(File, Line, Message), _)).

read_expressions(File, Expressions) :-
    must_be(atom, File),
    read_file_to_codes(File, Codes, []),
    parse_hddl(File, Codes, Expressions).


                 /*******************************
                 *            READING           *
                 *******************************/

%!  read_hddl(+DomainFile, +ProblemFile, -Task) is det.
%
%   Task is `hddl_task(Module, State, Tasks, Goal)`: Module a new module holding the
%   domain's operator/4 and method/4 facts (see htn.pl), State the initial facts, the
%   type facts included, Tasks the initial task network (a list, in order) and Goal the
%   literals of the state goal (`[]` when the problem has none).
%
%   @error hddl(File, Line, Message) for a syntax error or an unsupported feature

read_hddl(DomainFile, ProblemFile, hddl_task(Module, State, Tasks, Goal)) :-
    read_expressions(DomainFile, DomainExprs),
    read_expressions(ProblemFile, ProblemExprs),
    domain(DomainFile, DomainExprs, Domain),
    problem(ProblemFile, ProblemExprs, Domain, Problem),
    Domain = domain(_, _, Types, Constants, _, _, _, _),
    Problem = problem(_, Objects, RootParams, Roots, Init, Goal),
    append(Constants, Objects, AllObjects),
    type_facts(AllObjects, Types, TypeFacts),
    append(Init, TypeFacts, State0),
    sort(State0, State),
    gensym(hddl_domain_, Module),
    assert_domain(Module, Domain, RootParams, Roots, Tasks).

assert_domain(Module, domain(_, _, _, _, _, _, Operators, Methods), RootParams, Roots, Tasks) :-
    forall(member(O, Operators), assertz(Module:O)),
    forall(member(M, Methods), assertz(Module:M)),
    (   RootParams == []
    ->  Tasks = Roots
    ;   %   The problem's own parameters: a root method that types them lazily.
        maplist(lazy_type, RootParams, Pre),
        assertz(Module:method('__top_method', '__top', Pre, Roots)),
        Tasks = ['__top']
    ).

lazy_type(V-T, lazy('$type'(T, V))).


                 /*******************************
                 *             DOMAIN           *
                 *******************************/

%   domain(Name, Requirements, Types, Constants, Predicates, TaskDecls, Operators,
%   Methods): Types a list of Type-Parent, Constants of Object-Type, Predicates and
%   TaskDecls of Name/Arity, Operators operator/4 and Methods method/4 terms.

domain(File, Exprs, domain(Name, Reqs, Types, Constants, Preds, TaskDecls, Operators, Methods)) :-
    (   member(l(_, [define, l(_, [domain, Name])|Sections]), Exprs)
    ->  true
    ;   Exprs = [l(Line, _)|_]
    ->  hddl_error(File, Line, "not an HDDL domain: (define (domain NAME) ...) expected", [])
    ;   hddl_error(File, 1, "not an HDDL domain: the file is empty", [])
    ),
    forall(member(S, Sections), domain_section(File, S)),
    section_items(':requirements', Sections, Reqs, _),
    forall(member(l(L, [':requirements'|Rs]), Sections), maplist(requirement(File, L), Rs)),
    section_items(':types', Sections, TypeItems, TypesLine),
    typed_list(File, TypesLine, TypeItems, Types0),
    maplist(type_parent, Types0, Types),
    section_items(':constants', Sections, ConstItems, ConstLine),
    typed_list(File, ConstLine, ConstItems, Constants),
    (   memberchk(l(_, [':predicates'|PredDecls]), Sections)
    ->  maplist(predicate_decl(File), PredDecls, Preds)
    ;   Preds = any
    ),
    findall(T, ( member(l(L, [':task'|Body]), Sections), task_decl(File, L, Body, T) ), TaskDecls),
    findall(N/A, member(N/A-_, TaskDecls), TaskKeys),
    Env0 = env(File, Types, Constants, Preds, any),
    findall(O-K, ( member(l(L, [':action'|Body]), Sections), action(Env0, L, Body, O, K) ), OpKeys),
    pairs_keys_values(OpKeys, Operators, ActionKeys),
    forall(( member(K, ActionKeys), memberchk(K, TaskKeys) ),
           ( K = N/_, section_line(Sections, ':action', N, L),
             hddl_error(File, L, "~w is both an action and a task", [N]) )),
    append(ActionKeys, TaskKeys, Known),
    Env = env(File, Types, Constants, Preds, Known),
    findall(M, ( member(l(L, [':method'|Body]), Sections), method(Env, TaskKeys, L, Body, M) ),
            Methods).

domain_section(File, l(Line, [Key|_])) :-
    !,
    (   memberchk(Key, [':requirements', ':types', ':constants', ':predicates', ':task', ':method',
                        ':action'])
    ->  true
    ;   memberchk(Key-Feature, [':functions'-"numeric fluents (:functions)",
                                ':durative-action'-"durative actions",
                                ':derived'-"derived predicates (:derived)",
                                ':constraints'-"domain :constraints"])
    ->  hddl_error(File, Line, "~s are not supported", [Feature])
    ;   hddl_error(File, Line, "unknown domain section ~w", [Key])
    ).
domain_section(File, Item) :-
    hddl_error(File, 1, "unexpected ~w in the domain: a section (:keyword ...) expected", [Item]).

section_line(Sections, Key, Name, Line) :-
    (   member(l(Line, [Key, Name|_]), Sections) -> true ; Line = 0 ).

requirement(File, Line, R) :-
    (   memberchk(R, [':strips', ':typing', ':negative-preconditions', ':hierarchy',
                      ':method-preconditions', ':equality', ':universal-preconditions',
                      ':existential-preconditions', ':quantified-preconditions',
                      ':disjunctive-preconditions', ':conditional-effects', ':adl'])
    ->  true
    ;   hddl_error(File, Line, "requirement ~w is not supported", [R])
    ).

section_items(Key, Sections, Items, Line) :-
    (   memberchk(l(Line, [Key|Items0]), Sections)
    ->  Items = Items0
    ;   Items = [], Line = 0
    ).

%   typed_list(+File, +Line, +Items, -Pairs): `a b - t c` is [a-t, b-t, c-object];
%   a type may be `(either t1 t2)`, read as either([t1, t2]).
typed_list(_, _, [], []) :- !.
typed_list(File, Line, Items, Pairs) :-
    append(Names, ['-', Type0|Rest], Items),
    \+ memberchk('-', Names), !,
    type_name(File, Line, Type0, Type),
    check_names(File, Line, Names),
    findall(N-Type, member(N, Names), Typed),
    typed_list(File, Line, Rest, More),
    append(Typed, More, Pairs).
typed_list(File, Line, Items, Pairs) :-
    (   memberchk('-', Items)
    ->  hddl_error(File, Line, "a '-' without a type after it", [])
    ;   true
    ),
    check_names(File, Line, Items),
    findall(N-object, member(N, Items), Pairs).

check_names(File, Line, Names) :-
    forall(member(N, Names),
           (   ( atom(N) ; N = var(_) )
           ->  true
           ;   N = l(L, _)
           ->  hddl_error(File, L, "a name expected, not a list", [])
           ;   hddl_error(File, Line, "a name expected, not ~w", [N])
           )).

type_name(_, _, T, T) :-
    atom(T), !.
type_name(File, _, l(L, [either|Ts]), either(Sorted)) :- !,
    (   Ts \== [], maplist(atom, Ts)
    ->  sort(Ts, Sorted)
    ;   hddl_error(File, L, "(either TYPE ...) expects type names", [])
    ).
type_name(File, Line, T, _) :-
    (   T = l(L, _) -> true ; L = Line ),
    hddl_error(File, L, "a type name expected", []).

%   A type declared as a subtype of (either a b) is a subtype of each.
type_parent(T-either(Ps), T-Ps) :- !.
type_parent(T-P, T-[P]).

predicate_decl(File, l(Line, [Name|Params]), Name/Arity) :-
    atom(Name), !,
    typed_list(File, Line, Params, Typed),
    length(Typed, Arity).
predicate_decl(File, l(Line, _), _) :- !,
    hddl_error(File, Line, "a predicate declaration (name ?x ...) expected", []).
predicate_decl(File, Item, _) :-
    hddl_error(File, 1, "a predicate declaration (name ?x ...) expected, not ~w", [Item]).

task_decl(File, Line, [Name|Body], Name/Arity-Params) :-
    atom(Name), !,
    keywords(File, Line, Body, Pairs),
    (   memberchk(':parameters'-l(PL, Ps), Pairs) -> true ; Ps = [], PL = Line ),
    typed_list(File, PL, Ps, Params),
    length(Params, Arity).
task_decl(File, Line, _, _) :-
    hddl_error(File, Line, "(:task NAME :parameters (...)) expected", []).

keywords(_, _, [], []) :- !.
keywords(File, Line, [K, V|Rest], [K-V|Pairs]) :-
    atom(K), sub_atom(K, 0, 1, _, :), !,
    keywords(File, Line, Rest, Pairs).
keywords(File, Line, [K|_], _) :-
    hddl_error(File, Line, "a keyword with a value expected, not ~w", [K]).

%   The parameters as a variable map: an assoc from name to var-Type.
param_map(Params, Map, Vars) :-
    empty_assoc(Empty),
    foldl(add_param, Params, Vars, Empty, Map).

add_param(var(Name)-Type, V-Type, Map0, Map) :-
    put_assoc(Name, Map0, V-Type, Map).


                 /*******************************
                 *            ACTIONS           *
                 *******************************/

action(Env, Line, [Name|Body], operator(Head, Pre, Del, Add), Name/Arity) :-
    atom(Name), !,
    Env = env(File, _, _, _, _),
    keywords(File, Line, Body, Pairs),
    forall(member(K-_, Pairs),
           (   memberchk(K, [':parameters', ':precondition', ':effect'])
           ->  true
           ;   hddl_error(File, Line, "action ~w: unknown keyword ~w", [Name, K])
           )),
    (   memberchk(':parameters'-l(PL, Ps), Pairs) -> true ; Ps = [], PL = Line ),
    typed_list(File, PL, Ps, Params),
    check_variables(File, PL, Params),
    param_map(Params, Map, VarTypes),
    length(Params, Arity),
    pairs_keys(VarTypes, Vars),
    Head =.. [Name|Vars],
    (   memberchk(':precondition'-PreExpr, Pairs) -> true ; PreExpr = l(Line, []) ),
    formula_conjuncts(Env, Map, Line, PreExpr, Conjuncts),
    place(Conjuncts, VarTypes, [], eager, Pre),
    (   memberchk(':effect'-EffExpr, Pairs) -> true ; EffExpr = l(Line, []) ),
    effects(Env, Map, Line, EffExpr, Effects),
    partition([add(_)]>>true, Effects, Adds, Dels),
    maplist(arg(1), Adds, Add),
    maplist(arg(1), Dels, Del).
action(Env, Line, _, _, _) :-
    Env = env(File, _, _, _, _),
    hddl_error(File, Line, "(:action NAME ...) expected", []).

check_variables(File, Line, Params) :-
    forall(member(P-_, Params),
           (   P = var(_)
           ->  true
           ;   hddl_error(File, Line, "a parameter must be a ?variable, not ~w", [P])
           )).

effects(Env, Map, Line, Expr, Effects) :-
    Env = env(File, _, _, _, _),
    (   Expr = l(L, Items) -> true ; L = Line, Items = Expr ),
    (   Items == []
    ->  Effects = []
    ;   Items = [and|Es]
    ->  maplist(effects(Env, Map, L), Es, Lists),
        append(Lists, Effects)
    ;   Items = [not, Atom]
    ->  atom_term(Env, Map, L, Atom, A),
        Effects = [del(A)]
    ;   Items = [when|_]
    ->  hddl_error(File, L, "conditional effects (when) are not supported", [])
    ;   Items = [forall|_]
    ->  hddl_error(File, L, "universally quantified effects (forall) are not supported", [])
    ;   Items = [Op|_], memberchk(Op, [increase, decrease, assign, 'scale-up', 'scale-down'])
    ->  hddl_error(File, L, "numeric effects (~w) are not supported", [Op])
    ;   atom_term(Env, Map, L, Expr, A),
        Effects = [add(A)]
    ).


                 /*******************************
                 *           FORMULAS           *
                 *******************************/

%   A formula is read into a list of conjuncts, each pos(Atom) (an atom of the state)
%   or other(Literal, Vars) (any other literal of htn.pl, with the variables it needs
%   bound).

formula_conjuncts(Env, Map, Line, Expr, Conjuncts) :-
    Env = env(File, _, _, _, _),
    (   Expr = l(L, Items) -> true ; L = Line, Items = Expr ),
    (   Items == []
    ->  Conjuncts = []
    ;   Items = [and|Fs]
    ->  maplist(formula_conjuncts(Env, Map, L), Fs, Lists),
        append(Lists, Conjuncts)
    ;   Items = [not, F]
    ->  negation(Env, Map, L, F, Conjuncts)
    ;   Items = [=, X, Y]
    ->  term_arg(Env, Map, L, X, TX),
        term_arg(Env, Map, L, Y, TY),
        term_variables(TX-TY, Vs),
        Conjuncts = [other(TX = TY, Vs)]
    ;   Items = [or|Fs]
    ->  maplist(sub_formula(Env, Map, L), Fs, Alts),
        term_variables(Alts, Vs),
        Conjuncts = [other(or(Alts), Vs)]
    ;   Items = [imply, A, B]
    ->  sub_formula(Env, Map, L, A, LA),
        sub_formula(Env, Map, L, B, LB),
        term_variables(LA-LB, Vs),
        Conjuncts = [other(or([[not(LA)], LB]), Vs)]
    ;   Items = [forall, l(QL, QVars), F]
    ->  quantified(Env, Map, QL, QVars, F, Map1, Local, Gen),
        sub_formula(Env, Map1, L, F, Test),
        outer_variables(Gen-Test, Local, Vs),
        Conjuncts = [other(forall(Gen, Test), Vs)]
    ;   Items = [exists, l(QL, QVars), F]
    ->  quantified(Env, Map, QL, QVars, F, Map1, Local, _),
        formula_conjuncts(Env, Map1, L, F, Inner),
        place(Inner, Local, [], eager, Lits),
        outer_variables(Lits, Local, Vs),
        Conjuncts = [other(or([Lits]), Vs)]
    ;   Items = [K|_], memberchk(K, [when, forall, exists, imply])
    ->  hddl_error(File, L, "malformed ~w", [K])
    ;   Items = [K|_], memberchk(K, [>, <, >=, =<, '<='])
    ->  hddl_error(File, L, "numeric comparisons (~w) are not supported", [K])
    ;   atom_term(Env, Map, L, Expr, A),
        Conjuncts = [pos(A)]
    ).

negation(Env, Map, L, F, [other(Lit, Vs)]) :-
    (   F = l(_, [=, X, Y])
    ->  term_arg(Env, Map, L, X, TX),
        term_arg(Env, Map, L, Y, TY),
        Lit = (TX \= TY)
    ;   sub_formula(Env, Map, L, F, Lits),
        Lit = not(Lits)
    ),
    term_variables(Lit, Vs).

%   sub_formula: a formula inside a connective, its own free variables left to the
%   conjunction around it.
sub_formula(Env, Map, L, F, Lits) :-
    formula_conjuncts(Env, Map, L, F, Conjuncts),
    place(Conjuncts, [], [], eager, Lits).

quantified(Env, Map, QL, QVars, _F, Map1, Local, Gen) :-
    Env = env(File, _, _, _, _),
    typed_list(File, QL, QVars, Typed),
    check_variables(File, QL, Typed),
    foldl(add_param, Typed, Local, Map, Map1),
    maplist(type_lit, Local, Gen).

type_lit(V-T, '$type'(T, V)).

outer_variables(Term, Local, Vs) :-
    term_variables(Term, All),
    pairs_keys(Local, LocalVars),
    exclude(var_in(LocalVars), All, Vs).

var_in(Vars, V) :-
    member(W, Vars), W == V, !.

atom_term(Env, Map, Line, Expr, Term) :-
    Env = env(File, _, _, Preds, _),
    (   Expr = l(L, [Name|Args]), atom(Name)
    ->  maplist(term_arg(Env, Map, L), Args, TArgs),
        length(Args, Arity),
        check_predicate(File, L, Preds, Name, Arity),
        Term =.. [Name|TArgs]
    ;   atom(Expr), Expr \== []
    ->  check_predicate(File, Line, Preds, Expr, 0),
        Term = Expr
    ;   Expr = l(L, _)
    ->  hddl_error(File, L, "an atom (predicate arg ...) expected", [])
    ;   hddl_error(File, Line, "an atom (predicate arg ...) expected, not ~w", [Expr])
    ).

check_predicate(_, _, any, _, _) :- !.
check_predicate(File, Line, Preds, Name, Arity) :-
    (   memberchk(Name/Arity, Preds)
    ->  true
    ;   memberchk(Name/Declared, Preds)
    ->  hddl_error(File, Line, "predicate ~w has ~d arguments here but ~d in :predicates",
                   [Name, Arity, Declared])
    ;   hddl_error(File, Line, "predicate ~w is not declared in :predicates", [Name])
    ).

term_arg(Env, Map, Line, var(Name), V) :- !,
    (   get_assoc(Name, Map, V-_)
    ->  true
    ;   Env = env(File, _, _, _, _),
        hddl_error(File, Line, "variable ?~w is not a parameter here", [Name])
    ).
term_arg(_, _, _, A, A) :-
    atom(A), !.
term_arg(Env, _, Line, l(L, _), _) :- !,
    Env = env(File, _, _, _, _),
    (   L == 0 -> L1 = Line ; L1 = L ),
    hddl_error(File, L1, "an argument (a ?variable or an object) expected, not a list", []).
term_arg(Env, _, Line, X, _) :-
    Env = env(File, _, _, _, _),
    hddl_error(File, Line, "an argument expected, not ~w", [X]).

%   place(+Conjuncts, +Params, +Seen, +Rest, -Lits): the literals of a conjunction
%   in the order the planner evaluates them: the atoms first, in the order written,
%   each followed by the type checks of the parameters it binds; then the other
%   literals, each after type literals that bind its parameters still unbound; last
%   the parameters nothing bound: `eager` binds them by type, `lazy` types them lazily
%   (Lazy: those of the list, the others are only checked to exist).
place(Conjuncts, Params, Seen0, Rest, Lits) :-
    partition([pos(_)]>>true, Conjuncts, Positives, Others),
    foldl(place_atom(Params), Positives, PosLists, Seen0, Seen1),
    foldl(place_other(Params), Others, OtherLists, Seen1, Seen2),
    exclude(seen(Seen2), Params, Unseen),
    maplist(place_unseen(Rest), Unseen, RestLits),
    append([PosLists, OtherLists, [RestLits]], Lists0),
    append(Lists0, Lits).

place_atom(Params, pos(A), [A|Types], Seen0, Seen) :-
    term_variables(A, Vs),
    new_params(Params, Vs, Seen0, New, Seen),
    maplist(type_lit, New, Types).

place_other(Params, other(Lit, Vs), Lits, Seen0, Seen) :-
    new_params(Params, Vs, Seen0, New, Seen),
    maplist(type_lit, New, Types),
    append(Types, [Lit], Lits).

new_params(Params, Vs, Seen0, New, Seen) :-
    include(param_of(Vs), Params, New0),
    exclude(seen(Seen0), New0, New),
    pairs_keys(New, NewVars),
    append(Seen0, NewVars, Seen).

param_of(Vs, V-_) :-
    var_in(Vs, V).

seen(Seen, V-_) :-
    var_in(Seen, V).

place_unseen(eager, V-T, '$type'(T, V)).
place_unseen(lazy(Used), V-T, Lit) :-
    (   var_in(Used, V)
    ->  Lit = lazy('$type'(T, V))
    ;   Lit = not([not(['$type'(T, V)])])
    ).


                 /*******************************
                 *            METHODS           *
                 *******************************/

method(Env, TaskKeys, Line, [Name|Body], method(Name, Task, Pre, Subtasks)) :-
    atom(Name), !,
    Env = env(File, _, _, _, _),
    keywords(File, Line, Body, Pairs),
    forall(member(K-_, Pairs),
           (   memberchk(K, [':parameters', ':task', ':precondition', ':ordered-subtasks',
                             ':ordered-tasks', ':subtasks', ':tasks', ':ordering', ':constraints'])
           ->  true
           ;   hddl_error(File, Line, "method ~w: unknown keyword ~w", [Name, K])
           )),
    (   memberchk(':parameters'-l(PL, Ps), Pairs) -> true ; Ps = [], PL = Line ),
    typed_list(File, PL, Ps, Params),
    check_variables(File, PL, Params),
    param_map(Params, Map, VarTypes),
    (   memberchk(':task'-TaskExpr, Pairs)
    ->  task_term(Env, Map, Line, TaskExpr, Task),
        functor(Task, TName, TArity),
        (   memberchk(TName/TArity, TaskKeys)
        ->  true
        ;   hddl_error(File, Line, "method ~w decomposes ~w/~d, which is not a declared :task",
                       [Name, TName, TArity])
        )
    ;   hddl_error(File, Line, "method ~w has no :task", [Name])
    ),
    (   memberchk(':precondition'-PreExpr, Pairs) -> true ; PreExpr = l(Line, []) ),
    formula_conjuncts(Env, Map, Line, PreExpr, Conjuncts0),
    (   memberchk(':constraints'-CExpr, Pairs)
    ->  formula_conjuncts(Env, Map, Line, CExpr, CConjuncts)
    ;   CConjuncts = []
    ),
    append(Conjuncts0, CConjuncts, Conjuncts),
    network(Env, Map, Line, Name, Pairs, Subtasks),
    term_variables(Task-Subtasks, Used),
    place(Conjuncts, VarTypes, [], lazy(Used), Pre).
method(Env, _, Line, _, _) :-
    Env = env(File, _, _, _, _),
    hddl_error(File, Line, "(:method NAME ...) expected", []).

task_term(Env, Map, Line, Expr, Task) :-
    Env = env(File, _, _, _, _),
    (   Expr = l(L, [Name|Args]), atom(Name)
    ->  maplist(term_arg(Env, Map, L), Args, TArgs),
        Task =.. [Name|TArgs]
    ;   atom(Expr), Expr \== []
    ->  Task = Expr
    ;   Expr = l(L, _)
    ->  hddl_error(File, L, "a task (name arg ...) expected", [])
    ;   hddl_error(File, Line, "a task (name arg ...) expected, not ~w", [Expr])
    ).

%   network(+Env, +Map, +Line, +Owner, +Pairs, -Tasks): the subtasks in their total
%   order, from :ordered-subtasks (or :ordered-tasks), or from :subtasks (or :tasks)
%   and :ordering.
network(Env, Map, Line, Owner, Pairs, Tasks) :-
    Env = env(File, _, _, _, _),
    (   member(K, [':ordered-subtasks', ':ordered-tasks']), memberchk(K-Expr, Pairs)
    ->  subtask_list(Env, Map, Line, Expr, Labelled),
        pairs_values(Labelled, Tasks)
    ;   member(K, [':subtasks', ':tasks']), memberchk(K-Expr, Pairs)
    ->  subtask_list(Env, Map, Line, Expr, Labelled),
        (   memberchk(':ordering'-OExpr, Pairs) -> true ; OExpr = l(Line, []) ),
        ordering(File, Line, OExpr, Before),
        total_order(File, Line, Owner, Labelled, Before, Tasks)
    ;   Tasks = []
    ).

subtask_list(Env, Map, Line, Expr, Labelled) :-
    (   Expr = l(L, Items) -> true ; L = Line, Items = Expr ),
    (   Items == []
    ->  Labelled = []
    ;   Items = [and|Es]
    ->  foldl(subtask(Env, Map, L), Es, Labelled, 0, _)
    ;   subtask(Env, Map, L, Expr, Entry, 0, _),
        Labelled = [Entry]
    ).

subtask(Env, Map, Line, Expr, Label-Task, N0, N) :-
    N is N0 + 1,
    (   Expr = l(L, [Label0, l(TL, TItems)]), atom(Label0)
    ->  Label = Label0,
        task_term(Env, Map, L, l(TL, TItems), Task)
    ;   Label = '$unlabelled'(N0),
        (   Expr = l(L, _) -> true ; L = Line ),
        task_term(Env, Map, L, Expr, Task)
    ),
    known_task(Env, L, Task).

%   known_task(+Env, +Line, +Task): Task is a declared task or an action.
known_task(env(File, _, _, _, Known), Line, Task) :-
    functor(Task, Name, Arity),
    (   Known == any
    ->  true
    ;   memberchk(Name/Arity, Known)
    ->  true
    ;   memberchk(Name/Other, Known)
    ->  hddl_error(File, Line, "~w has ~d arguments here but ~d where it is declared", [Name, Arity, Other])
    ;   hddl_error(File, Line, "~w/~d is neither a task nor an action", [Name, Arity])
    ).

ordering(File, Line, Expr, Before) :-
    (   Expr = l(L, Items) -> true ; L = Line, Items = Expr ),
    (   Items == []
    ->  Before = []
    ;   Items = [and|Os]
    ->  maplist(ordering(File, L), Os, Lists),
        append(Lists, Before)
    ;   Items = [<, A, B], atom(A), atom(B)
    ->  Before = [A-B]
    ;   Items = [>, A, B], atom(A), atom(B)
    ->  Before = [B-A]
    ;   hddl_error(File, L, "an ordering constraint (< task1 task2) expected", [])
    ).

%   total_order(+File, +Line, +Owner, +Labelled, +Before, -Tasks): the one order of
%   the subtasks that Before allows; an error when it allows more than one (partial
%   order) or none (a cycle).
total_order(File, Line, Owner, Labelled, Before, Tasks) :-
    pairs_keys(Labelled, Labels),
    forall(member(A-B, Before),
           forall(member(X, [A, B]),
                  (   memberchk(X, Labels)
                  ->  true
                  ;   hddl_error(File, Line, "~w: the :ordering names ~w, which is no subtask's id",
                                 [Owner, X])
                  ))),
    order(File, Line, Owner, Labels, Before, Order),
    maplist(label_task(Labelled), Order, Tasks).

label_task(Labelled, Label, Task) :-
    memberchk(Label-Task, Labelled).

order(_, _, _, [], _, []) :- !.
order(File, Line, Owner, Labels, Before, [First|Order]) :-
    include(no_predecessor(Labels, Before), Labels, Free),
    (   Free = [First]
    ->  selectchk(First, Labels, Rest),
        order(File, Line, Owner, Rest, Before, Order)
    ;   Free = [A, B|_]
    ->  hddl_error(File, Line,
                   "partial order is not supported: ~w leaves subtasks ~w and ~w unordered",
                   [Owner, A, B])
    ;   hddl_error(File, Line, "~w: the :ordering has a cycle", [Owner])
    ).

no_predecessor(Labels, Before, L) :-
    \+ ( member(P-L, Before), memberchk(P, Labels) ).


                 /*******************************
                 *            PROBLEM           *
                 *******************************/

%   problem(Name, Objects, RootParams, Roots, Init, Goal)

problem(File, Exprs, Domain, problem(Name, Objects, RootParams, Roots, Init, Goal)) :-
    Domain = domain(_, _, Types, Constants, Preds, TaskDecls, Operators, _),
    (   member(l(_, [define, l(_, [problem, Name])|Sections]), Exprs)
    ->  true
    ;   Exprs = [l(Line, _)|_]
    ->  hddl_error(File, Line, "not an HDDL problem: (define (problem NAME) ...) expected", [])
    ;   hddl_error(File, 1, "not an HDDL problem: the file is empty", [])
    ),
    forall(member(S, Sections), problem_section(File, S)),
    %   The problem's (:domain NAME) is not checked against the domain's name: IPC
    %   instances exist whose names differ (2020 partial-order Transport).
    forall(member(l(L, [':requirements'|Rs]), Sections), maplist(requirement(File, L), Rs)),
    section_items(':objects', Sections, ObjItems, ObjLine),
    typed_list(File, ObjLine, ObjItems, Objects),
    append(Constants, Objects, All),
    forall(member(_-T, All), check_type(File, ObjLine, Types, T)),
    findall(N/A, member(N/A-_, TaskDecls), TaskKeys),
    findall(N/A, ( member(operator(H, _, _, _), Operators), functor(H, N, A) ), ActionKeys),
    append(TaskKeys, ActionKeys, Known),
    Env = env(File, Types, Constants, Preds, Known),
    empty_assoc(Empty),
    section_items(':init', Sections, InitItems, InitLine),
    maplist(init_fact(Env, Empty, InitLine, All), InitItems, Init),
    (   memberchk(l(HL, [':htn'|HtnBody]), Sections)
    ->  keywords(File, HL, HtnBody, Pairs),
        (   memberchk(':parameters'-l(PL, Ps), Pairs) -> true ; Ps = [], PL = HL ),
        typed_list(File, PL, Ps, Params),
        check_variables(File, PL, Params),
        param_map(Params, Map, RootParams),
        network(Env, Map, HL, 'the problem\'s :htn', Pairs, Roots)
    ;   RootParams = [], Roots = []
    ),
    (   memberchk(l(GL, [':goal', GoalExpr]), Sections)
    ->  formula_conjuncts(Env, Empty, GL, GoalExpr, Conjuncts),
        place(Conjuncts, [], [], eager, Goal)
    ;   Goal = []
    ).

problem_section(File, l(Line, [Key|_])) :-
    !,
    (   memberchk(Key, [':domain', ':requirements', ':objects', ':htn', ':init', ':goal'])
    ->  true
    ;   memberchk(Key-Feature, [':constraints'-"problem :constraints",
                                ':metric'-"plan metrics (:metric)"])
    ->  hddl_error(File, Line, "~s are not supported", [Feature])
    ;   hddl_error(File, Line, "unknown problem section ~w", [Key])
    ).
problem_section(File, Item) :-
    hddl_error(File, 1, "unexpected ~w in the problem: a section (:keyword ...) expected", [Item]).

check_type(_, _, _, object) :- !.
check_type(_, _, Types, T) :-
    atom(T), memberchk(T-_, Types), !.
check_type(_, _, Types, T) :-
    atom(T), member(_-Ps, Types), memberchk(T, Ps), !.
check_type(File, Line, Types, either(Ts)) :- !,
    maplist(check_type(File, Line, Types), Ts).
check_type(File, Line, _, T) :-
    hddl_error(File, Line, "type ~w is not declared in :types", [T]).

init_fact(Env, Map, Line, Objects, Expr, Fact) :-
    Env = env(File, _, _, _, _),
    (   Expr = l(L, [=|_])
    ->  hddl_error(File, L, "numeric fluents in :init are not supported", [])
    ;   Expr = l(L, [not|_])
    ->  hddl_error(File, L, ":init lists the atoms that hold; (not ...) is not allowed there", [])
    ;   true
    ),
    atom_term(Env, Map, Line, Expr, Fact),
    Fact =.. [_|Args],
    (   Expr = l(FL, _) -> true ; FL = Line ),
    forall(member(A, Args),
           (   memberchk(A-_, Objects)
           ->  true
           ;   hddl_error(File, FL, "object ~w is not declared in :objects or :constants", [A])
           )).


                 /*******************************
                 *             TYPES            *
                 *******************************/

%   type_facts(+Objects, +Types, -Facts): '$type'(T, O) for each object O and each
%   type T it belongs to (its declared types and their ancestors, and object), and
%   for each (either ...) type used, the objects of its member types.
type_facts(Objects, Types, Facts) :-
    findall('$type'(T, O),
            ( member(O-T0, Objects),
              declared_type(T0, T1),
              ancestor(Types, T1, T)
            ),
            Facts0),
    findall(either(Ts), ( sub_term(either(Ts), Types) ; member(_-either(Ts), Objects) ), Eithers0),
    sort(Eithers0, Eithers),
    findall('$type'(either(Ts), O),
            ( member(either(Ts), Eithers),
              member('$type'(T, O), Facts0),
              memberchk(T, Ts)
            ),
            EitherFacts),
    findall('$type'(object, O), member(O-_, Objects), ObjectFacts),
    append([Facts0, EitherFacts, ObjectFacts], Facts1),
    sort(Facts1, Facts).

declared_type(either(Ts), T) :- !,
    member(T, Ts).
declared_type(T, T).

ancestor(_, T, T).
ancestor(Types, T, A) :-
    ancestor(Types, T, A, [T]).

ancestor(Types, T, A, Visited) :-
    member(T-Parents, Types),
    member(P, Parents),
    \+ memberchk(P, Visited),
    (   A = P
    ;   ancestor(Types, P, A, [P|Visited])
    ).


                 /*******************************
                 *            SOLVING           *
                 *******************************/

%!  hddl_solve(+DomainFile, +ProblemFile, +Options, -Result) is det.
%
%   Read the two files and plan with htn_plan/5.  Result is as htn_plan/5's.  Options
%   are those of htn_plan/5 (time_limit(S), max_nodes(N)); the problem's goal is
%   added.  Reading counts against the time limit.

hddl_solve(DomainFile, ProblemFile, Options, Result) :-
    get_time(T0),
    read_hddl(DomainFile, ProblemFile, hddl_task(Module, State, Tasks, Goal)),
    (   select_option(time_limit(Limit), Options, Options1)
    ->  get_time(T1),
        Left is max(0, Limit - (T1 - T0)),
        Options2 = [time_limit(Left)|Options1]
    ;   Options2 = Options
    ),
    merge_options([goal(Goal)], Options2, PlanOptions),
    htn_plan(Module, State, Tasks, PlanOptions, Result0),
    (   Result0 = no_plan(time_limit(_)), nonvar(Limit)
    ->  Result = no_plan(time_limit(Limit))
    ;   Result = Result0
    ).

%!  solve_cli is det.
%
%   The entry of `ita htn solve`, run in a child process that the parent kills at its
%   time limit: the last four command-line arguments are DomainFile, ProblemFile,
%   Seconds and MaxNodes (`inf` for none).  Writes one line, quoted and in functional
%   notation: `plan(Steps, Tree)`, `no_plan(Reason)` or `error(File, Line, Message)`,
%   and halts.

solve_cli :-
    current_prolog_flag(argv, Argv),
    append(_, [Domain, Problem, TimeText, NodesText], Argv), !,
    atom_number(TimeText, Time),
    (   NodesText == inf -> Nodes = inf ; atom_number(NodesText, Nodes) ),
    catch(cli_result(Domain, Problem, Time, Nodes, Result),
          Error,
          error_result(Error, Problem, Result)),
    write_term(Result, [quoted(true), ignore_ops(true), brace_terms(false), numbervars(false)]),
    nl,
    halt(0).
solve_cli :-
    format(user_error, "usage: solve_cli Domain Problem Seconds MaxNodes~n", []),
    halt(2).

cli_result(Domain, Problem, Time, Nodes, Result) :-
    get_time(T0),
    hddl_solve(Domain, Problem, [time_limit(Time), max_nodes(Nodes)], Result0),
    get_time(T1),
    Seconds is T1 - T0,
    (   Result0 = plan(Steps, Tree, _)
    ->  Result = plan(Steps, Tree, Seconds)
    ;   Result0 = no_plan(Reason),
        Result = no_plan(Reason, Seconds)
    ).

error_result(error(hddl(File, Line, Message), _), _, error(File, Line, Message)) :- !.
error_result(error(existence_error(source_sink, File), _), _, error(File, 0, "no such file")) :- !.
error_result(Error, Problem, error(Problem, 0, Message)) :-
    (   catch(message_to_codes(Error, Codes), _, fail)
    ->  string_codes(Message, Codes)
    ;   format(string(Message), "~q", [Error])
    ).

message_to_codes(Error, Codes) :-
    '$messages':translate_message(Error, Lines, []),
    with_output_to(codes(Codes0), print_message_lines(current_output, '', Lines)),
    maplist([C0, C]>>( C0 == 0'\n -> C = 0'\s ; C = C0 ), Codes0, Codes).
