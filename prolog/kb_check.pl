:- module(kb_check,
          [ undefined_calls/2           % +Modules, -Undefined
          ]).

/** <module> Find predicates that are called but defined nowhere

Used by `ita kb check`.  Load errors and warnings (syntax errors, singleton variables,
discontiguous clauses) are collected while loading, by py_bridge:load_source_files/2;
this module adds the calls that no loaded or autoloadable predicate answers.
*/

:- use_module(library(prolog_codewalk)).
:- use_module(library(apply)).
:- use_module(library(error)).
:- use_module(library(lists)).

:- thread_local found/4.

%!  undefined_calls(+Modules:list(atom), -Undefined:list) is det.
%
%   Undefined is the sorted list of calls in the clauses of Modules to predicates that
%   are defined nowhere, each as `undefined(Callee, Caller, File, Line)`: Callee and
%   Caller are `Module:Name/Arity` indicators, File and Line locate the calling clause.

undefined_calls(Modules, Undefined) :-
    must_be(list(atom), Modules),
    retractall(found(_, _, _, _)),
    forall(member(Module, Modules),
           prolog_walk_code([ undefined(trace),
                              on_trace(kb_check:record_undefined),
                              module(Module),
                              source(false),
                              infer_meta_predicates(false)
                            ])),
    findall(undefined(Callee, Caller, File, Line),
            retract(found(Callee, Caller, File, Line)),
            Undefined0),
    sort(Undefined0, Undefined).

:- public record_undefined/3.

record_undefined(Callee, Caller, Location) :-
    indicator(Callee, CalleePI),
    indicator(Caller, CallerPI),
    location(Location, File, Line),
    assertz(found(CalleePI, CallerPI, File, Line)).

indicator(Module:Head, Module:Name/Arity) :-
    callable(Head), !,
    functor(Head, Name, Arity).
indicator(Term, Term).

location(clause(Ref), File, Line) :-
    clause_property(Ref, file(File)),
    clause_property(Ref, line_count(Line)), !.
location(clause_term_position(Ref, _), File, Line) :-
    location(clause(Ref), File, Line), !.
location(file(File, Line, _, _), File, Line) :- !.
location(_, '', 0).
