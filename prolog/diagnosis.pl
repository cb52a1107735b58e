:- module(diagnosis,
          [ posterior/4,                % +Exception, +Context, +Counts, -Posterior
            consistent/5,               % +Causes, +Test, +Outcome, +Context, -Remaining
            outcome_partition/4,        % +Causes, +Test, +Context, -Partition
            select_test/6,              % +Posterior, +Tests, +Context, +Method, -Choice, -Expected
            decision_tree/6,            % +Posterior, +Tests, +Context, +Method, -Tree, -Expected
            tree_cost/3,                % +Tree, +Posterior, -Expected
            problem_tree/5,             % +Probs, +Tests, +Method, -Tree, -Expected
            step/7,                     % +Exception, +Context, +Counts, +Results, +Tests, +Method, -Reply
            isolated/4                  % +Exception, +Context, +Results, -Cause
          ]).

/** <module> The Exception Handler's engine: posterior over causes and test selection

On an exception, the certainty of the causes the fault knowledge base (kb/faults.pl)
links to it is set from their frequencies (posterior/4: stated priors as pseudo-counts
plus the counts learned across runs, times the likelihood that the cause shows as that
exception).  Tests are then selected, executed by the caller in the cell, and
interpreted (consistent/5) until one cause is isolated or no test can separate the rest.

*Test selection* (the seed: "by dynamically generating a near-minimal decision tree
according to fault frequency, test cost, and test precondition information"), with the
cost of each test given by the caller with the set-up of its preconditions priced in
from the arm's state (moves, tool changes):

  * `optimal`: the exact minimum-expected-cost decision tree, by dynamic programming over
    the sets of causes still possible (each set a bit mask; tabled), for up to
    MaxExact causes;
  * `rollout`: one-step rollout on the greedy rule: each test is priced by its cost plus
    the expected cost of the greedy trees below it;
  * `greedy`: information gain per unit cost;
  * `cheapest`: the cheapest test that separates anything.

`auto` is `optimal` up to 20 causes (16 causes and 16 tests take tens of milliseconds)
and `rollout` beyond.  A tree is `leaf(Cause)`,
`unresolved(Causes)` (no test separates them) or `node(Test, [Outcome-Tree, ...])`.
Tests are `test(Name, Cost, Outcomes)` with Outcomes the outcome of each cause of the
problem in order, so the selection itself knows nothing of kb/faults.pl and can be
benchmarked on random instances (problem_tree/5).
*/

:- use_module(library(apply)).
:- use_module(library(error)).
:- use_module(library(lists)).
:- use_module(library(pairs)).
:- use_module(library(aggregate)).
:- use_module('../kb/faults', [candidate_causes/3, prior/2, instantiate_cause/3, test_outcome/4]).
:- reexport('../kb/faults', [isolated/4]).

:- dynamic problem_prob/2.              % problem_prob(Index, P): the problem being solved
:- dynamic problem_test/3.              % problem_test(Name, Cost, Masks): outcome class masks

:- table opt/3.


                 /*******************************
                 *           POSTERIOR          *
                 *******************************/

%!  posterior(+Exception, +Context:list, +Counts:list, -Posterior:list) is det.
%
%   Posterior is `Cause-P` for the causes of Exception in Context (kb/faults.pl), P
%   proportional to (prior + learned count) times the likelihood, normalised, most
%   probable first.  Counts are `Name-N`, the learned count of each cause by name
%   (`broken_probe`), missing names count 0.
%
%   @error existence_error(exception, Exception) for an unknown exception

posterior(Exception, Context, Counts, Posterior) :-
    must_be(list, Counts),
    candidate_causes(Exception, Context, Candidates),
    maplist(weight(Context, Counts), Candidates, Weighted),
    sum_list_values(Weighted, Total),
    (   Total > 0
    ->  maplist(normalise(Total), Weighted, Normal),
        sort(2, @>=, Normal, Posterior)
    ;   Posterior = []
    ).

weight(Context, Counts, Cause-Likelihood, Cause-W) :-
    functor(Cause, Name, _),
    (   prior(Template, Prior),
        instantiate_cause(Template, Context, Cause)
    ->  true
    ;   Prior = 1
    ),
    (   memberchk(Name-N, Counts) -> true ; N = 0 ),
    W is (Prior + N) * Likelihood.

sum_list_values(Pairs, Total) :-
    pairs_values(Pairs, Values),
    sum_list(Values, Total).

normalise(Total, C-W, C-P) :-
    P is W / Total.


                 /*******************************
                 *     INTERPRETING RESULTS     *
                 *******************************/

%!  consistent(+Causes:list, +Test, +Outcome, +Context:list, -Remaining:list) is det.
%
%   Remaining are the `Cause-P` of Causes whose predicted outcome of Test is Outcome,
%   renormalised.

consistent(Causes, Test, Outcome, Context, Remaining) :-
    include(predicts_outcome(Test, Outcome, Context), Causes, Kept),
    sum_list_values(Kept, Total),
    (   Total > 0
    ->  maplist(normalise(Total), Kept, Remaining)
    ;   Remaining = Kept
    ).

predicts_outcome(Test, Outcome, Context, Cause-_) :-
    test_outcome(Test, Cause, Context, Outcome).

%!  outcome_partition(+Causes:list, +Test, +Context:list, -Partition:list) is det.
%
%   Partition is `Outcome-Causes` of Test over the `Cause-P` pairs Causes.

outcome_partition(Causes, Test, Context, Partition) :-
    findall(O-(C-P), ( member(C-P, Causes), test_outcome(Test, C, Context, O) ), Pairs),
    keysort(Pairs, Sorted),
    group_pairs_by_key(Sorted, Partition).

%   isolated/4 (re-exported from kb/faults.pl): the one cause consistent with every test
%   result, for `ita kb why`.

                 /*******************************
                 *        TEST SELECTION        *
                 *******************************/

%!  select_test(+Posterior:list, +Tests:list, +Context:list, +Method, -Choice, -Expected) is det.
%
%   Choice is `test(Name)` (the root of the Method's decision tree over the causes of
%   Posterior, `Cause-P`), `isolated(Cause)` when one cause is left, or
%   `unresolved(Causes)` when no test of Tests (`Name-Cost`) separates them.  Expected
%   is the tree's expected cost of testing.

select_test(Posterior, Tests, Context, Method, Choice, Expected) :-
    decision_tree(Posterior, Tests, Context, Method, Tree, Expected),
    root_choice(Tree, Choice).

root_choice(leaf(C), isolated(C)).
root_choice(unresolved(Cs), unresolved(Cs)).
root_choice(node(T, _), test(T)).

%!  decision_tree(+Posterior:list, +Tests:list, +Context:list, +Method, -Tree, -Expected) is det.
%
%   Tree is Method's decision tree over the causes of Posterior with the tests Tests
%   (`Name-Cost`, cost in simulated seconds), outcomes from kb/faults.pl in Context;
%   Expected its expected cost.  Method: `optimal`, `rollout`, `greedy`, `cheapest` or
%   `auto`.
%
%   @error domain_error(diagnosis_method, Method) for another Method

decision_tree(Posterior, Tests, Context, Method, Tree, Expected) :-
    must_be(list, Posterior),
    must_be(list, Tests),
    pairs_keys_values(Posterior, Causes, Probs),
    maplist(problem_test(Causes, Context), Tests, Problem),
    problem_tree(Probs, Problem, Method, Tree0, Expected),
    name_tree(Tree0, Causes, Tree).

problem_test(Causes, Context, Name-Cost, test(Name, Cost, Outcomes)) :-
    maplist(cause_outcome(Name, Context), Causes, Outcomes).

cause_outcome(Test, Context, Cause, Outcome) :-
    test_outcome(Test, Cause, Context, Outcome).

name_tree(leaf(I), Causes, leaf(C)) :-
    nth0(I, Causes, C).
name_tree(unresolved(Is), Causes, unresolved(Cs)) :-
    maplist(cause_at(Causes), Is, Cs).
name_tree(node(T, Branches0), Causes, node(T, Branches)) :-
    maplist(name_branch(Causes), Branches0, Branches).

cause_at(Causes, I, C) :-
    nth0(I, Causes, C).

name_branch(Causes, O-S0, O-S) :-
    name_tree(S0, Causes, S).

%!  problem_tree(+Probs:list, +Tests:list, +Method, -Tree, -Expected) is det.
%
%   The decision tree of an abstract problem: causes 0..n-1 with probabilities Probs,
%   tests `test(Name, Cost, Outcomes)` (Outcomes: one outcome per cause).  Leaves name
%   causes by index.  For benchmarks and for decision_tree/6.

problem_tree(Probs, Tests, Method0, Tree, Expected) :-
    must_be(oneof([optimal, rollout, greedy, cheapest, auto]), Method0),
    length(Probs, N),
    (   Method0 == auto
    ->  ( N =< 20 -> Method = optimal ; Method = rollout )
    ;   Method = Method0
    ),
    abolish_all_tables,
    setup_problem(Probs, Tests),
    All is (1 << N) - 1,
    (   N =:= 0
    ->  Tree = unresolved([]), Expected = 0.0
    ;   Method == optimal
    ->  opt(All, Expected0, Tree),
        Expected is float(Expected0)
    ;   heuristic_tree(Method, All, Tree),
        tree_expected(Tree, All, Expected)
    ),
    abolish_all_tables.

setup_problem(Probs, Tests) :-
    retractall(problem_prob(_, _)),
    retractall(problem_test(_, _, _)),
    forall(nth0(I, Probs, P), assertz(problem_prob(I, P))),
    forall(member(test(Name, Cost, Outcomes), Tests),
           ( outcome_masks(Outcomes, Masks),
             assertz(problem_test(Name, Cost, Masks)) )).

%   outcome_masks(+Outcomes, -Masks): Outcome-Mask of the causes with each outcome.

outcome_masks(Outcomes, Masks) :-
    findall(O-I, nth0(I, Outcomes, O), Pairs),
    keysort(Pairs, Sorted),
    group_pairs_by_key(Sorted, Groups),
    maplist(group_mask, Groups, Masks).

group_mask(O-Is, O-M) :-
    foldl(set_bit, Is, 0, M).

set_bit(I, M0, M) :-
    M is M0 \/ (1 << I).

%   mass(+S, -P): the probability of the causes in S (tabled: a set is met often).

:- table mass/2.

mass(S, P) :-
    mass_(S, 0, 0.0, P).

mass_(0, _, P, P) :- !.
mass_(S, I, P0, P) :-
    (   S /\ 1 =:= 1
    ->  problem_prob(I, Q),
        P1 is P0 + Q
    ;   P1 = P0
    ),
    S1 is S >> 1,
    I1 is I + 1,
    mass_(S1, I1, P1, P).

%   split(+S, +Masks, -Parts): the non-empty parts Outcome-(S /\ Mask).

split(_, [], []).
split(S, [O-M|Ms], Parts) :-
    X is S /\ M,
    (   X =:= 0
    ->  split(S, Ms, Parts)
    ;   Parts = [O-X|Parts1],
        split(S, Ms, Parts1)
    ).

separates(S, Name, Cost, Parts) :-
    problem_test(Name, Cost, Masks),
    split(S, Masks, Parts),
    Parts = [_, _|_].

single(S) :-
    S /\ (S - 1) =:= 0.

bits(S, Is) :-
    bits_(S, 0, Is).

bits_(0, _, []) :- !.
bits_(S, I, Is) :-
    S1 is S >> 1,
    I1 is I + 1,
    (   S /\ 1 =:= 1
    ->  Is = [I|Is1]
    ;   Is = Is1
    ),
    bits_(S1, I1, Is1).

%   opt(+S, -Expected, -Tree) is det.  (tabled)
%
%   The minimum expected cost of isolating the cause within S, given that it is in S,
%   and the tree that reaches it.

opt(S, 0, Leaf) :-
    single(S), !,
    bits(S, [I]),
    Leaf = leaf(I).
opt(S, E, Tree) :-
    mass(S, PS),
    findall(C0-(Name-Parts), separates(S, Name, C0, Parts), Candidates),
    (   ( Candidates == [] ; PS =< 0 )
    ->  bits(S, Is), E = 0, Tree = unresolved(Is)
    ;   best_candidate(Candidates, PS, inf, none, E, Best),
        Best = Name-Branches,
        Tree = node(Name, Branches)
    ).

%   best_candidate(+Candidates, +PS, +E0, +Best0, -E, -Best): the test of least
%   expected cost; a test whose own cost already exceeds the best is not explored.

best_candidate([], _, E, Best, E, Best).
best_candidate([C0-(Name-Parts)|Cs], PS, E0, Best0, E, Best) :-
    (   C0 >= E0
    ->  best_candidate(Cs, PS, E0, Best0, E, Best)
    ;   sub_cost(Parts, PS, C0, E0, Cost, Branches),
        (   Cost < E0
        ->  best_candidate(Cs, PS, Cost, Name-Branches, E, Best)
        ;   best_candidate(Cs, PS, E0, Best0, E, Best)
        )
    ).

%   sub_cost(+Parts, +PS, +E0, +Bound, -E, -Branches): E0 plus the expected cost of the
%   parts' subtrees; stops (E = inf) once it passes Bound.

sub_cost([], _, E, _, E, []).
sub_cost([O-X|Parts], PS, E0, Bound, E, [O-T|Ts]) :-
    mass(X, PX),
    opt(X, EX, T),
    E1 is E0 + PX / PS * EX,
    (   E1 >= Bound
    ->  E = inf, Ts = []
    ;   sub_cost(Parts, PS, E1, Bound, E, Ts)
    ).

%   heuristic_tree(+Method, +S, -Tree): greedy, cheapest-first or rollout trees.

heuristic_branch(Method, O-X, O-T) :-
    heuristic_tree(Method, X, T).

heuristic_tree(_, S, leaf(I)) :-
    single(S), !,
    bits(S, [I]).
heuristic_tree(Method, S, Tree) :-
    findall(C-(Name-Parts), separates(S, Name, C, Parts), Candidates),
    (   Candidates == []
    ->  bits(S, Is), Tree = unresolved(Is)
    ;   choose(Method, S, Candidates, Name-Parts),
        maplist(heuristic_branch(Method), Parts, Branches),
        Tree = node(Name, Branches)
    ).

choose(cheapest, _, Candidates, Best) :-
    keysort(Candidates, [_-Best|_]).
choose(greedy, S, Candidates, Best) :-
    mass(S, PS),
    entropy(S, PS, H),
    findall(Score-T, ( member(C-T, Candidates), T = _-Parts,
                       gain(Parts, PS, H, G), Score is -(G / max(C, 1.0e-9)) ),
            Scored),
    keysort(Scored, [_-Best|_]).
choose(rollout, S, Candidates, Best) :-
    mass(S, PS),
    findall(E-T, ( member(C-T, Candidates), T = _-Parts,
                   rollout_below(Parts, PS, 0.0, Below),
                   E is C + Below ),
            Scored),
    keysort(Scored, [_-Best|_]).

rollout_below([], _, E, E).
rollout_below([_-X|Parts], PS, E0, E) :-
    greedy_cost(X, EX),
    mass(X, PX),
    E1 is E0 + PX / PS * EX,
    rollout_below(Parts, PS, E1, E).

%   greedy_cost(+S, -E): the expected cost of the greedy tree over S (tabled).

:- table greedy_cost/2.

greedy_cost(S, E) :-
    (   single(S)
    ->  E = 0.0
    ;   findall(C-(Name-Parts), separates(S, Name, C, Parts), Candidates),
        (   Candidates == []
        ->  E = 0.0
        ;   choose(greedy, S, Candidates, Name-Parts),
            problem_test(Name, C, _),
            mass(S, PS),
            rollout_below(Parts, PS, C, E)
        )
    ).

entropy(S, PS, H) :-
    aggregate_all(sum(-(Q / PS) * log(Q / PS)),
                  ( problem_prob(I, Q), Q > 0, S /\ (1 << I) =\= 0 ), H).

part_entropy(PS, _-X, A0, A1) :-
    mass(X, PX),
    entropy(X, PX, HX),
    A1 is A0 + PX / PS * HX.

gain(Parts, PS, H, G) :-
    foldl(part_entropy(PS), Parts, 0, Hafter),
    G is H - Hafter.

%   tree_expected(+Tree, +S, -E): the expected cost of Tree for the causes in S.

tree_expected(leaf(_), _, 0.0).
tree_expected(unresolved(_), _, 0.0).
tree_expected(node(Name, Branches), S, E) :-
    problem_test(Name, C, Masks),
    mass(S, PS),
    foldl(branch_expected(Masks, S, PS), Branches, 0, Below),
    E is C + Below.

branch_expected(Masks, S, PS, O-T, E0, E1) :-
    memberchk(O-M, Masks),
    X is S /\ M,
    mass(X, PX),
    tree_expected(T, X, EX),
    E1 is E0 + PX / PS * EX.

%!  tree_cost(+Tree, +Posterior:list, -Expected) is det.
%
%   The expected cost of a named decision tree (decision_tree/6) over the `Cause-P`
%   pairs Posterior, the costs of its tests taken from the tree's last problem.

tree_cost(Tree, Posterior, Expected) :-
    pairs_keys(Posterior, Causes),
    length(Causes, N),
    All is (1 << N) - 1,
    name_tree(Indexed, Causes, Tree),
    tree_expected(Indexed, All, Expected).


                 /*******************************
                 *       THE CALLER'S STEP      *
                 *******************************/

narrow(Context, T-O, C0, C1) :-
    consistent(C0, T, O, Context, C1).

%!  step(+Exception, +Context:list, +Counts:list, +Results:list, +Tests:list, +Method, -Reply) is det.
%
%   One step of a diagnosis, for the Python facade in one bridge call: the posterior
%   of Exception's causes in Context (posterior/4, with the learned Counts), narrowed by
%   the test Results so far (`Test-Outcome`), and the next choice over the Tests the cell
%   can run now (`Name-Cost`, not yet run).  Reply is
%   `[Choice, Expected, Posterior, Remaining]` with Choice `test(Name)`,
%   `isolated(Cause)` or `unresolved(Causes)`, Posterior and Remaining as `Cause-P`
%   lists (before and after the results).

step(Exception, Context, Counts, Results, Tests, Method, [Choice, Expected, Posterior, Remaining]) :-
    posterior(Exception, Context, Counts, Posterior),
    foldl(narrow(Context), Results, Posterior, Remaining),
    (   Remaining == []
    ->  Choice = unresolved([]), Expected = 0.0
    ;   select_test(Remaining, Tests, Context, Method, Choice, Expected)
    ).
