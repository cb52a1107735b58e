:- module(htn,
          [ htn_plan/5,                 % +Domain, +State, +Tasks, +Options, -Result
            htn_replan/5,               % +Domain, +State, +Network, +Options, -Result
            htn_remaining/3,            % +Tree, +Done, -Network
            htn_check_domain/1          % +Domain
          ]).

/** <module> A total-order HTN planner (SHOP2 family, progression search)

The domain is data: a module holding two kinds of facts,

  - `operator(Head, Pre, Del, Add)`: the primitive task Head (a callable term) is
    applicable when the literals of Pre hold; it deletes the atoms of Del and then adds
    those of Add (an atom both deleted and added is present afterwards);
  - `method(Name, Task, Pre, Subtasks)`: the compound task Task may be done by the
    ordered list Subtasks when Pre holds in the state where the method starts.  Name
    (an atom, or a term whose functor is the method's name) is what the decomposition
    tree records.

Clauses are tried in the order they are written (the author orders methods, as in
SHOP2).  Every subtask must be the head of an operator or the task of a method.

*Literals* (Pre is a list, a conjunction, evaluated left to right):

  - `Atom`: a fact of the state.  A predicate that no operator adds or deletes is
    *static*: its facts are kept in an indexed table, the others in the search state;
  - `not(Lit)` or `not(Lits)`: negation as failure; its variables should be bound
    by the literals before it (an unbound one reads "no binding makes it true");
  - `X = Y`, `X \= Y`: equality (unification) and its negation;
  - `or(Alternatives)`: a list of literal lists, one of which holds;
  - `forall(Generator, Test)`: two literal lists; Test holds for every solution of
    Generator;
  - `call(Goal)`: an *attached procedure*: Goal is called in the domain module and may
    bind variables (a predicate that asks Python, a geometric test...);
  - `lazy(Atom)`: a static fact checked as soon as its variables are bound, and at the
    latest when the plan is complete (a variable still unbound then is bound by it).
    The HDDL front end types its method parameters this way, so a parameter no
    precondition binds stays a variable until an action binds it (lifted search).

A variable left unbound by a method's preconditions is carried into its subtasks;
an action must be ground once its preconditions hold.

*Search*: depth-first, left to right, from the current state (progression), with
backtracking over methods and bindings.  Every search node (the remaining task network
and the state, up to variable renaming) is entered once per iteration (its SHA-1 in a
trie), which is the loop check for recursive methods and the memo of failed nodes at
once.  The network's length is bounded (initially twice the root network's plus 8);
when an iteration fails and the bound cut some branch, the bound is doubled and the
search starts again; when none was cut the problem has no plan (`exhausted`).  A
problem without a plan whose methods recurse without end (left recursion that grows
the network without acting) is therefore only stopped by the limits:
time_limit(Seconds) and max_nodes(N) (nodes entered).

*Result*: `plan(Steps, Tree, State)` or `no_plan(Reason)`.  Steps is the list of
`Id-Action` in execution order; State the final state (a sorted list of facts);
Tree is `tree(RootIds, Nodes)` with a node per task, in the order they were
decomposed:

  - `primitive(Id, Action, Calls)`;
  - `decomposed(Id, Task, Method, ChildIds, Calls)`,

Calls being the `call/1` goals of the operator's or method's preconditions as they
were answered.  Reason is `exhausted` (there is no plan), `time_limit(Seconds)` or
`node_limit(N)`.
*/

:- use_module(library(apply)).
:- use_module(library(error)).
:- use_module(library(lists)).
:- use_module(library(option)).
:- use_module(library(ordsets)).
:- use_module(library(pairs)).
:- use_module(library(aggregate)).
:- use_module(library(assoc)).


                 /*******************************
                 *            ENTRIES           *
                 *******************************/

%!  htn_plan(+Domain:atom, +State:list, +Tasks:list, +Options:list, -Result) is det.
%
%   Plan the ordered task network Tasks from the state State (a list of ground facts)
%   with the operators and methods of the module Domain.  The root tasks get the ids
%   0, 1, ... in order.  Options:
%
%     - goal(Lits): literals that must hold in the final state (default `[]`);
%     - time_limit(Seconds): give up after this wall time (default: none);
%     - max_nodes(N): give up after entering N search nodes (default: none).
%
%   @error existence_error(htn_task, Name/Arity) for a task no operator or method has
%   @error type_error/2 for a malformed domain, state or task

htn_plan(Domain, State, Tasks, Options, Result) :-
    must_be(list, Tasks),
    length(Tasks, N),
    (   N =:= 0 -> Ids = [] ; Last is N - 1, numlist(0, Last, Ids) ),
    pairs_keys_values(Network, Ids, Tasks),
    merge_options(Options, [next_id(N)], Options1),
    htn_replan(Domain, State, Network, Options1, Result).

%!  htn_replan(+Domain:atom, +State:list, +Network:list, +Options:list, -Result) is det.
%
%   Plan again from State for the remaining task network Network, a list of `Id-Task`
%   (the ids of an earlier plan's tree, see htn_remaining/3, so the new tree hangs
%   under the old one).  New nodes are numbered from the option next_id(N) (default:
%   one more than the largest id of Network).  Other options and Result as htn_plan/5.

htn_replan(Domain, State, Network, Options, Result) :-
    must_be(atom, Domain),
    must_be(list, State),
    must_be(list, Network),
    must_be(list, Options),
    maplist(network_entry, Network, Entries),
    pairs_keys(Network, Ids),
    max_list([-1|Ids], MaxId),
    Next0 is MaxId + 1,
    option(next_id(Next), Options, Next0),
    option(goal(Goal), Options, []),
    must_be(list, Goal),
    limits(Options, Limits),
    in_temporary_module(Tmp,
                        true,
                        plan_in(Tmp, Domain, State, Entries, Ids, Next, Goal, Limits, Result)).

network_entry(Entry, t(Id, Task)) :-
    (   Entry = Id-Task, integer(Id), callable(Task)
    ->  true
    ;   type_error(htn_network_entry, Entry)
    ).

limits(Options, limits(Deadline, Seconds, MaxNodes)) :-
    (   option(time_limit(Seconds), Options)
    ->  must_be(number, Seconds),
        (   Seconds >= 0 -> true ; domain_error(nonneg_seconds, Seconds) ),
        get_time(Now),
        Deadline is Now + Seconds
    ;   Deadline = inf, Seconds = inf
    ),
    option(max_nodes(MaxNodes), Options, inf).

%!  htn_check_domain(+Domain:atom) is det.
%
%   Check that the facts of Domain are well formed: lists where lists belong, callable
%   heads and tasks, literals of the forms above, and every subtask an operator's head
%   or a method's task.
%
%   @error type_error/2, existence_error(htn_task, Name/Arity) or
%   permission_error(define, htn_task, Name/Arity) (a task both primitive and compound)

htn_check_domain(Domain) :-
    must_be(atom, Domain),
    in_temporary_module(Tmp, true, compile_domain(Tmp, Domain)).

%!  htn_remaining(+Tree, +Done:nonneg, -Network:list) is det.
%
%   Network is what remains of the plan whose tree is Tree once its first Done actions
%   have been executed, as `Id-Task` pairs for htn_replan/5: a task none of whose
%   actions has run stays whole (so it is decomposed afresh), a task all of whose
%   actions have run is gone, a task in between is replaced by its children.  A task
%   with no actions counts as done when an action after it has run.

htn_remaining(tree(Roots, Nodes), Done, Network) :-
    must_be(nonneg, Done),
    must_be(list, Roots),
    must_be(list, Nodes),
    empty_assoc(Empty),
    foldl(node_by_id, Nodes, Empty, Index),
    foldl(spans(Index), Roots, Spanned, 0, _),
    maplist(remaining(Done), Spanned, Lists),
    append(Lists, Network).

node_by_id(Node, Index0, Index) :-
    arg(1, Node, Id),
    put_assoc(Id, Index0, Node, Index).

%   spans(+Index, +Id, -Spanned, +First, -Last): the subtree of Id with the leaf
%   positions each node covers, span(Id, Task, First, Last, Children).
spans(Index, Id, span(Id, Task, First, Last, Children), First, Last) :-
    (   get_assoc(Id, Index, Node)
    ->  true
    ;   existence_error(htn_tree_node, Id)
    ),
    (   Node = primitive(Id, Task, _)
    ->  Children = [], Last is First + 1
    ;   Node = decomposed(Id, Task, _, ChildIds, _),
        foldl(spans(Index), ChildIds, Children, First, Last)
    ).

remaining(Done, span(Id, Task, First, Last, Children), List) :-
    (   First >= Done
    ->  List = [Id-Task]
    ;   Last =< Done
    ->  List = []
    ;   maplist(remaining(Done), Children, Lists),
        append(Lists, List)
    ).


                 /*******************************
                 *          COMPILATION         *
                 *******************************/

%   The domain and the static facts are compiled into a temporary module Tmp:
%
%     '$dynamic'(Name, Arity, Index)   a predicate some operator changes
%     '$primitive'(Name, Arity)        an operator's head
%     '$op'(Head, Pre, Del, Add, Calls)
%     '$method'(Task, Name, Pre, Subtasks, Calls)
%     '$htn:Name'(Args...)             the static facts of Name
%
%   Literals compile to d(Index, Atom) (a dynamic fact), s(Goal) (a static fact),
%   n(Lits), eq(X, Y), neq(X, Y), or(Alternatives), fa(Generator, Test), c(Goal) and
%   lz(Goal).

compile_domain(Tmp, Domain) :-
    (   current_module(Domain) -> true ; existence_error(htn_domain, Domain) ),
    dynamic([ Tmp:'$dynamic'/3, Tmp:'$primitive'/2, Tmp:'$op'/4, Tmp:'$method'/5 ]),
    domain_facts(Domain, operator(_, _, _, _), Operators),
    domain_facts(Domain, method(_, _, _, _), Methods),
    maplist(check_operator, Operators),
    maplist(check_method, Methods),
    dynamic_keys(Operators, Keys),
    forall(nth1(I, Keys, Name/Arity), assertz(Tmp:'$dynamic'(Name, Arity, I))),
    forall(member(operator(H, _, _, _), Operators),
           ( functor(H, Name, Arity),
             ( Tmp:'$primitive'(Name, Arity) -> true ; assertz(Tmp:'$primitive'(Name, Arity)) ) )),
    forall(member(method(_, T, _, _), Methods),
           ( functor(T, Name, Arity),
             (   Tmp:'$primitive'(Name, Arity)
             ->  permission_error(define, htn_task, Name/Arity)
             ;   true
             ) )),
    forall(member(method(_, _, _, Subtasks), Methods),
           forall(member(S, Subtasks), check_task_known(Tmp, Methods, S))),
    forall(member(Op, Operators), compile_operator(Tmp, Domain, Op)),
    forall(member(M, Methods), compile_method(Tmp, Domain, M)).

domain_facts(Domain, Head, Facts) :-
    functor(Head, Name, Arity),
    (   current_predicate(Domain:Name/Arity)
    ->  findall(Head, Domain:Head, Facts)
    ;   Facts = []
    ).

check_operator(operator(H, P, D, A)) :-
    must_be(callable, H),
    must_be(list, P),
    must_be(list, D),
    must_be(list, A),
    maplist(must_be(callable), D),
    maplist(must_be(callable), A).

check_method(method(N, T, P, S)) :-
    must_be(callable, N),
    must_be(callable, T),
    must_be(list, P),
    must_be(list, S),
    maplist(must_be(callable), S).

check_task_known(Tmp, Methods, Task) :-
    functor(Task, Name, Arity),
    (   Tmp:'$primitive'(Name, Arity)
    ->  true
    ;   functor(T, Name, Arity),
        memberchk(method(_, T, _, _), Methods)
    ->  true
    ;   existence_error(htn_task, Name/Arity)
    ).

dynamic_keys(Operators, Keys) :-
    findall(Name/Arity,
            ( member(operator(_, _, D, A), Operators),
              ( member(X, D) ; member(X, A) ),
              functor(X, Name, Arity)
            ),
            Keys0),
    sort(Keys0, Keys).

compile_operator(Tmp, Domain, operator(Head, Pre, Del, Add)) :-
    compile_lits(Tmp, Domain, Pre, CPre),
    calls(Pre, Calls),
    maplist(effect(Tmp, del), Del, CDel),
    maplist(effect(Tmp, add), Add, CAdd),
    append(CDel, CAdd, Effects0),
    keysort(Effects0, Effects1),
    group_pairs_by_key(Effects1, Effects),
    assertz(Tmp:'$op'(Head, CPre, Effects, Calls)).

%   An effect is Index-del(Atom) or Index-add(Atom); the operator keeps them grouped
%   by the index of their predicate.
effect(Tmp, Kind, Atom, I-E) :-
    functor(Atom, Name, Arity),
    once(Tmp:'$dynamic'(Name, Arity, I)),
    E =.. [Kind, Atom].

compile_method(Tmp, Domain, method(Name, Task, Pre, Subtasks)) :-
    compile_lits(Tmp, Domain, Pre, CPre),
    calls(Pre, Calls),
    assertz(Tmp:'$method'(Task, Name, CPre, Subtasks, Calls)).

calls(Lits, Calls) :-
    phrase(call_lits(Lits), Calls).

call_lits([]) --> [].
call_lits([L|Ls]) --> call_lit(L), call_lits(Ls).

call_lit(L) --> { var(L) }, !.
call_lit(call(G)) --> !, [G].
call_lit(not(L)) --> !, call_sub(L).
call_lit(or(Alts)) --> !, call_alts(Alts).
call_lit(forall(G, T)) --> !, call_sub(G), call_sub(T).
call_lit(_) --> [].

call_sub(L) --> { is_list(L) }, !, call_lits(L).
call_sub(L) --> call_lit(L).

call_alts([]) --> [].
call_alts([A|As]) --> call_sub(A), call_alts(As).

compile_lits(Tmp, Domain, Lits, CLits) :-
    must_be(list, Lits),
    maplist(compile_lit(Tmp, Domain), Lits, CLits).

compile_lit(_, _, L, _) :-
    var(L), !,
    instantiation_error(L).
compile_lit(Tmp, Domain, not(L), n(C)) :- !,
    sub_lits(Tmp, Domain, L, C).
compile_lit(_, _, X = Y, eq(X, Y)) :- !.
compile_lit(_, _, X \= Y, neq(X, Y)) :- !.
compile_lit(Tmp, Domain, or(Alts), or(CAlts)) :- !,
    must_be(list, Alts),
    maplist(sub_lits(Tmp, Domain), Alts, CAlts).
compile_lit(Tmp, Domain, forall(G, T), fa(CG, CT)) :- !,
    sub_lits(Tmp, Domain, G, CG),
    sub_lits(Tmp, Domain, T, CT).
compile_lit(_, Domain, call(G), c(Domain:G)) :- !,
    must_be(callable, G).
compile_lit(Tmp, _, lazy(A), lz(G)) :- !,
    must_be(callable, A),
    (   static_goal(Tmp, A, G0)
    ->  G = G0
    ;   domain_error(static_literal, A)
    ).
compile_lit(Tmp, _, A, C) :-
    must_be(callable, A),
    functor(A, Name, Arity),
    (   Tmp:'$dynamic'(Name, Arity, I)
    ->  C = d(I, A)
    ;   static_goal(Tmp, A, G),
        C = s(G)
    ).

sub_lits(Tmp, Domain, L, C) :-
    (   is_list(L)
    ->  compile_lits(Tmp, Domain, L, C)
    ;   compile_lit(Tmp, Domain, L, C1),
        C = [C1]
    ).

%   static_goal(+Tmp, +Atom, -Goal): the goal that looks Atom up among the static
%   facts (a predicate of its own per name, so indexing works on all arguments).
static_goal(Tmp, A, Tmp:G) :-
    \+ ( functor(A, Name, Arity), Tmp:'$dynamic'(Name, Arity, _) ),
    A =.. [Name|Args],
    atom_concat('$htn:', Name, SName),
    G =.. [SName|Args],
    length(Args, Arity),
    (   current_predicate(Tmp:SName/Arity)
    ->  true
    ;   dynamic(Tmp:SName/Arity)
    ).

%   split_state(+Tmp, +Facts, -State, -Static): the static facts go to the temporary
%   module; the dynamic ones make the state, s(Facts1, ..., FactsK) with the sorted
%   facts of the K dynamic predicates.
split_state(Tmp, Facts, State, Static) :-
    must_be(list, Facts),
    maplist(check_fact, Facts),
    sort(Facts, Sorted),
    partition(is_dynamic(Tmp), Sorted, Dynamic, Static),
    forall(member(F, Static), ( static_goal(Tmp, F, G), assertz(G) )),
    aggregate_all(count, Tmp:'$dynamic'(_, _, _), K),
    map_list_to_pairs(fact_index(Tmp), Dynamic, Indexed),
    keysort(Indexed, ByIndex),
    group_pairs_by_key(ByIndex, Groups),
    numlist_or_empty(K, Is),
    maplist(facts_at(Groups), Is, Lists),
    State =.. [s|Lists].

numlist_or_empty(K, Is) :-
    (   K =:= 0 -> Is = [] ; numlist(1, K, Is) ).

facts_at(Groups, I, Facts) :-
    (   memberchk(I-Facts0, Groups) -> Facts = Facts0 ; Facts = [] ).

check_fact(F) :-
    (   callable(F), ground(F)
    ->  true
    ;   type_error(ground_fact, F)
    ).

is_dynamic(Tmp, F) :-
    functor(F, Name, Arity),
    Tmp:'$dynamic'(Name, Arity, _).

fact_index(Tmp, F, I) :-
    functor(F, Name, Arity),
    Tmp:'$dynamic'(Name, Arity, I).


                 /*******************************
                 *            SEARCH            *
                 *******************************/

plan_in(Tmp, Domain, Facts, Entries, Ids, Next, Goal, Limits, Result) :-
    compile_domain(Tmp, Domain),
    split_state(Tmp, Facts, State0, Static),
    forall(member(t(_, Task), Entries), check_root(Tmp, Task)),
    compile_lits(Tmp, Domain, Goal, CGoal),
    length(Entries, Len0),
    Bound0 is 2 * Len0 + 8,
    Counter = counter(0, false),
    catch(iterate(Bound0, Entries, Len0, State0, base(Tmp, CGoal, Limits, Counter), Next, Found),
          htn_limit(Reason),
          Found = no_plan(Reason)),
    (   Found = found(Steps, Nodes, State)
    ->  state_facts(State, Dynamic),
        append(Dynamic, Static, All),
        sort(All, Final),
        Result = plan(Steps, tree(Ids, Nodes), Final)
    ;   Result = Found
    ).

check_root(Tmp, Task) :-
    functor(Task, Name, Arity),
    (   Tmp:'$primitive'(Name, Arity) -> true
    ;   functor(T, Name, Arity), Tmp:'$method'(T, _, _, _, _) -> true
    ;   existence_error(htn_task, Name/Arity)
    ).

state_facts(State, Facts) :-
    (   compound(State)
    ->  State =.. [_|Lists],
        append(Lists, Facts)
    ;   Facts = []
    ).

%   iterate(+Bound, ...): a depth-first search with the network's length bounded by
%   Bound; again with twice the bound when that one cut a branch.
iterate(Bound, Entries, Len0, State0, Base, Next, Found) :-
    Base = base(Tmp, Goal, Limits, Counter),
    trie_new(Trie),
    Ctx = ctx(Tmp, Goal, Limits, Counter, Trie),
    nb_setarg(2, Counter, false),
    (   solve(Entries, Len0, Bound, State0, Ctx, Next, Steps, Nodes, State),
        bind_lazy(Steps-Nodes)
    ->  Found = found(Steps, Nodes, State)
    ;   arg(2, Counter, true)
    ->  Bound1 is Bound * 2,
        iterate(Bound1, Entries, Len0, State0, Base, Next, Found)
    ;   Found = no_plan(exhausted)
    ).

solve([], _, _, State, Ctx, _, [], [], State) :-
    arg(2, Ctx, Goal),
    holds(Goal, State).
solve([t(Id, Task)|Rest], Len, Bound, State0, Ctx, Next, Steps, Nodes, State) :-
    tick(Ctx),
    new_node([t(Id, Task)|Rest], State0, Ctx),
    arg(1, Ctx, Tmp),
    functor(Task, Name, Arity),
    (   Tmp:'$primitive'(Name, Arity)
    ->  Tmp:'$op'(Task, Pre, Effects, Calls),
        holds(Pre, State0),
        (   ground(Task) -> true ; instantiation_error(Task) ),
        apply_effects(Effects, State0, State1),
        Steps = [Id-Task|Steps1],
        Nodes = [primitive(Id, Task, Calls)|Nodes1],
        Len1 is Len - 1,
        solve(Rest, Len1, Bound, State1, Ctx, Next, Steps1, Nodes1, State)
    ;   Tmp:'$method'(Task, Method, Pre, Subtasks, Calls),
        holds(Pre, State0),
        length(Subtasks, N),
        Len1 is Len - 1 + N,
        within(Bound, Len1, Ctx),
        number_tasks(Subtasks, Next, Next1, Entries, ChildIds),
        append(Entries, Rest, Network),
        Nodes = [decomposed(Id, Task, Method, ChildIds, Calls)|Nodes1],
        solve(Network, Len1, Bound, State0, Ctx, Next1, Steps, Nodes1, State)
    ).

number_tasks([], Id, Id, [], []).
number_tasks([T|Ts], Id0, Id, [t(Id0, T)|Es], [Id0|Ids]) :-
    Id1 is Id0 + 1,
    number_tasks(Ts, Id1, Id, Es, Ids).

within(Bound, Len, Ctx) :-
    (   Len =< Bound
    ->  true
    ;   arg(4, Ctx, Counter),
        nb_setarg(2, Counter, true),
        fail
    ).

%   new_node(+Network, +State, +Ctx): fails when this network and state (up to
%   renaming of variables) were entered before in this iteration.  The trie holds
%   the SHA-1 of each node, not the node: a deep network's nodes would fill memory
%   (1.7 GB against 48 MB on the largest IPC Satellite instance here).
new_node(Network, State, Ctx) :-
    network_tasks(Network, Tasks),
    (   term_attvars(Tasks, [])
    ->  Key = k(State, Tasks)
    ;   copy_term(Tasks, Copy, Goals),
        Key = k(State, Copy, Goals)
    ),
    arg(5, Ctx, Trie),
    variant_sha1(Key, Hash),
    trie_insert(Trie, Hash).

network_tasks([], []).
network_tasks([t(_, T)|Es], [T|Ts]) :-
    network_tasks(Es, Ts).

tick(Ctx) :-
    arg(4, Ctx, Counter),
    arg(1, Counter, N0),
    N is N0 + 1,
    nb_setarg(1, Counter, N),
    arg(3, Ctx, limits(Deadline, Seconds, MaxNodes)),
    (   N > MaxNodes
    ->  throw(htn_limit(node_limit(MaxNodes)))
    ;   true
    ),
    (   N /\ 1023 =:= 0, Deadline \== inf, get_time(Now), Now > Deadline
    ->  throw(htn_limit(time_limit(Seconds)))
    ;   true
    ).


                 /*******************************
                 *      STATES AND LITERALS     *
                 *******************************/

holds([], _).
holds([L|Ls], S) :-
    lit(L, S),
    holds(Ls, S).

lit(d(I, A), S) :-
    arg(I, S, Facts),
    (   ground(A)
    ->  ord_memberchk(A, Facts)
    ;   member(A, Facts)
    ).
lit(s(G), _) :-
    call(G).
lit(n(Ls), S) :-
    \+ holds(Ls, S).
lit(eq(X, Y), _) :-
    X = Y.
lit(neq(X, Y), _) :-
    \+ X = Y.
lit(or(Alts), S) :-
    member(Ls, Alts),
    holds(Ls, S).
lit(fa(G, T), S) :-
    \+ ( holds(G, S), \+ holds(T, S) ).
lit(c(G), _) :-
    call(G).
lit(lz(G), _) :-
    lazy(G).

%   apply_effects(+Effects, +State0, -State): State0 with the effects (Index-Changes,
%   sorted by Index) applied; the fact lists of the other predicates are shared.
apply_effects([], S, S) :- !.
apply_effects(Effects, S0, S) :-
    functor(S0, F, K),
    functor(S, F, K),
    apply_effects(1, K, Effects, S0, S).

apply_effects(I, K, Effects, S0, S) :-
    (   I > K
    ->  true
    ;   arg(I, S0, Facts0),
        arg(I, S, Facts),
        (   Effects = [I-Changes|Effects1]
        ->  changes(Changes, Dels0, Adds0),
            sort(Dels0, Dels),
            sort(Adds0, Adds),
            ord_subtract(Facts0, Dels, Facts1),
            ord_union(Facts1, Adds, Facts)
        ;   Facts = Facts0,
            Effects1 = Effects
        ),
        I1 is I + 1,
        apply_effects(I1, K, Effects1, S0, S)
    ).

changes([], [], []).
changes([C|Cs], Dels, Adds) :-
    (   C = del(A)
    ->  Dels = [A|Dels1], changes(Cs, Dels1, Adds)
    ;   C = add(A),
        Adds = [A|Adds1], changes(Cs, Dels, Adds1)
    ).


                 /*******************************
                 *        LAZY LITERALS         *
                 *******************************/

%   lazy(+Goal): Goal (a static fact) now if it is ground, else as soon as its
%   variables are bound (an attribute htn on each of them).
lazy(G) :-
    term_variables(G, Vars),
    (   Vars == []
    ->  call(G)
    ;   maplist(add_lazy(G), Vars)
    ).

add_lazy(G, V) :-
    (   get_attr(V, htn, Gs)
    ->  put_attr(V, htn, [G|Gs])
    ;   put_attr(V, htn, [G])
    ).

attr_unify_hook(Goals, Other) :-
    (   var(Other)
    ->  (   get_attr(Other, htn, Gs)
        ->  append(Goals, Gs, All),
            put_attr(Other, htn, All)
        ;   put_attr(Other, htn, Goals)
        )
    ;   maplist(lazy, Goals)
    ).

attribute_goals(V) -->
    { get_attr(V, htn, Goals) },
    [ lazy(V, Goals) ].

%   bind_lazy(+Term): bind every variable of Term that still waits on a lazy literal
%   by that literal (the plan is complete: any binding it allows will do).
bind_lazy(Term) :-
    term_attvars(Term, Vars),
    include(waiting, Vars, Waiting),
    (   Waiting = [V|_]
    ->  get_attr(V, htn, [G|_]),
        call(G),
        bind_lazy(Term)
    ;   true
    ).

waiting(V) :-
    var(V),
    get_attr(V, htn, _).
