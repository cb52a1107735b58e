:- module(macrop_store,
          [ load_store/1,               % +File
            forget_store/1,             % +File
            reset_store/1,              % +File
            save_store/1,               % +File
            must_be_open/1,             % +File
            store_macrops/2,            % +File, -Macrops
            store_macrop/4,             % +File, +NameAndFormat, +Fields, -Stored
            store_counts/4,             % +File, -Lookups, -Hits, -Misses
            stored/4,                   % ?File, ?Id, ?NameAndFormat, ?Fields
            stored_hits/3,              % +File, +Id, -Hits
            store_generation/2,         % +File, -Generation
            hit_key/3,                  % +File, +Id, -Key
            count_lookup/2,             % +File, +Found
            count_hit/3                 % +File, +Id, +Key
          ]).

/** <module> The MACROP store: learned MACROPs in a file, with lookup counts

MACROPs persist in a Prolog file, one `macrop(Id, NameAndFormat, Fields, hits(N))`
clause each, a `store_counts(Lookups, Hits, Misses)` clause and a `written_hits(Name, N)`
clause per hand-written MACROP that was used, so a user can read the file or consult it.
A store is known by its file name, which the caller chooses; learned MACROPs live apart
from the hand-written ones of kb/macrops.pl.  A loaded store lives in memory; it is
written back to its file (atomically) only by save_store/1.  A lookup bumps one
counter, a flag.  The lookup index over a store is prolog/macrop.pl's.
*/

:- use_module(library(aggregate)).
:- use_module(library(apply)).
:- use_module(library(error)).
:- use_module(library(lists)).
:- use_module(library(readutil)).

% The loaded stores, in memory; save_store/1 writes one back to its file.  A lookup
% bumps one flag: the hits of the MACROP found (hit_key/3) or the misses of the store;
% the store's lookups and hits are the counts read from its file plus those bumps.
:- dynamic stored/4.            % stored(File, Id, NameAndFormat, Fields)
:- dynamic count_base/5.        % count_base(File, MissKey, Lookups, Hits, Misses): open
:- dynamic counted/3.           % counted(File, Id, Hits0): Id's hits, Hits0 from the file
:- dynamic generation/2.        % generation(File, G): changes when Ids may be reused

%!  stored(?File, ?Id, ?NameAndFormat, ?Fields) is nondet.
%
%   MACROP Id of the loaded store File.

%!  store_generation(+File, -Generation) is semidet.
%
%   Generation of the loaded store File: it changes whenever its MACROP numbers may be
%   reused (load_store/1, reset_store/1).

store_generation(File, Generation) :-
    generation(File, Generation).

%!  load_store(+File) is det.
%
%   Read the MACROP store File (an empty store if the file does not exist yet),
%   replacing what was read from it before, with its counts and a new generation.
%
%   @error syntax_error(...) if File is not a readable Prolog file
%   @error domain_error(macrop_store_term(File), Term) for a term that is not a store's

load_store(File) :-
    must_be(atom, File),
    forget_store(File),
    open_counts(File),
    new_generation(File),
    (   exists_file(File)
    ->  read_file_to_terms(File, Terms, []),
        maplist(load_term(File), Terms)
    ;   true
    ).

load_term(File, macrop(Id, Name, Fields, hits(Hits))) :- !,
    must_be(positive_integer, Id),
    must_be(list, Fields),
    must_be(nonneg, Hits),
    assertz(stored(File, Id, Name, Fields)),
    set_hits(File, Id, Hits).
load_term(File, store_counts(Lookups, Hits, Misses)) :- !,
    must_be(nonneg, Lookups),
    must_be(nonneg, Hits),
    must_be(nonneg, Misses),
    retract(count_base(File, MissKey, _, _, _)),
    assertz(count_base(File, MissKey, Lookups, Hits, Misses)).
load_term(File, written_hits(Name, Hits)) :- !,
    set_hits(File, kb(Name), Hits).
load_term(File, Term) :-
    domain_error(macrop_store_term(File), Term).

set_hits(File, Id, Hits) :-
    hit_key(File, Id, Key),
    flag(Key, _, Hits),
    retractall(counted(File, Id, _)),
    assertz(counted(File, Id, Hits)).

%!  hit_key(+File, +Id, -Key) is det.
%
%   Key names the flag that counts the hits of MACROP Id of store File.  A flag that is
%   not zero has a counted/3 clause, so that close_store/1 can reset it.

hit_key(File, Id, Key) :-
    format(atom(Key), '$macrop_hits ~w ~q', [File, Id]).

%   open_counts(+File)
%
%   Mark store File open with its lookup, hit and miss counts at zero.

open_counts(File) :-
    format(atom(MissKey), '$macrop_misses ~w', [File]),
    flag(MissKey, _, 0),
    assertz(count_base(File, MissKey, 0, 0, 0)).

%   close_counts(+File)
%
%   Forget the counts of store File: the hits of its MACROPs and its misses.

close_counts(File) :-
    forall(retract(counted(File, Id, _)),
           ( hit_key(File, Id, Key), flag(Key, _, 0) )),
    forall(retract(count_base(File, MissKey, _, _, _)),
           flag(MissKey, _, 0)).

new_generation(File) :-
    flag(macrop_store_generation, G, G + 1),
    retractall(generation(File, _)),
    assertz(generation(File, G)).

%!  forget_store(+File) is det.
%
%   Forget the store File: its MACROPs, counts and generation (the file is unchanged).

forget_store(File) :-
    must_be(atom, File),
    retractall(stored(File, _, _, _)),
    close_counts(File),
    retractall(generation(File, _)).

%!  reset_store(+File) is det.
%
%   Forget the learned MACROPs, the hits and the counts of the open store File, with a
%   new generation (the file is unchanged until save_store/1).
%
%   @error existence_error(macrop_store, File) if File is not open

reset_store(File) :-
    must_be_open(File),
    retractall(stored(File, _, _, _)),
    close_counts(File),
    open_counts(File),
    new_generation(File).

%!  save_store(+File) is det.
%
%   Write the open store File back to File (through a temporary file, so that a crash
%   never leaves half a store).  When a write fails (a full disk, the file-size limit)
%   the temporary file is removed, File is as it was, and the error names File.
%
%   @error existence_error(macrop_store, File) if File is not open
%   @error macrop_store_write(File, Reason) when it cannot be written, Reason the
%          system's (e.g. 'No space left on device'), in the formal term so that a
%          caller that sees only the formal term (the Python bridge) still has it

save_store(File) :-
    store_counts(File, Lookups, Hits, Misses),
    store_macrops(File, Macrops),
    findall(written_hits(Name, H),
            ( counted(File, kb(Name), _), stored_hits(File, kb(Name), H) ),
            Written),
    atom_concat(File, '.tmp', Tmp),
    open(Tmp, write, Out),
    catch(( write_store(Out, Lookups, Hits, Misses, Macrops, Written),
            close(Out),
            rename_file(Tmp, File)
          ),
          Error,
          ( close(Out, [force(true)]),
            catch(delete_file(Tmp), _, true),
            save_error(Error, File, Thrown),
            throw(Thrown)
          )).

%   save_error(+Error, +File, -Thrown)
%
%   The error save_store/1 throws for Error: an I/O error names File (not the stream of
%   its temporary file) with the system's reason; any other error is itself.

save_error(error(io_error(_, _), context(_, Reason)), File,
           error(macrop_store_write(File, Reason), context(save_store/1, _))) :-
    atom(Reason), !.
save_error(Error, _, Error).

:- multifile prolog:error_message//1.

prolog:error_message(macrop_store_write(File, Reason)) -->
    [ 'cannot write the MACROP store ~w: ~w'-[File, Reason] ].

write_store(Out, Lookups, Hits, Misses, Macrops, Written) :-
    format(Out, '%   Learned MACROPs of the ITA Operation Planner (prolog/macrop.pl, macrop_store.pl).~n', []),
    format(Out, '%   macrop(Id, NameAndFormat, Fields, hits(Hits)); read with open_store/1.~n~n', []),
    portray_clause(Out, store_counts(Lookups, Hits, Misses)),
    forall(member(W, Written), portray_clause(Out, W)),
    nl(Out),
    forall(member(M, Macrops), (portray_clause(Out, M), nl(Out))).

%!  must_be_open(+File) is det.
%
%   @error existence_error(macrop_store, File) if store File is not open

must_be_open(File) :-
    must_be(atom, File),
    (   count_base(File, _, _, _, _)
    ->  true
    ;   existence_error(macrop_store, File)
    ).

%!  store_macrops(+File, -Macrops:list) is det.
%
%   Macrops are the `macrop(Id, NameAndFormat, Fields, hits(N))` of the open store File.

store_macrops(File, Macrops) :-
    must_be_open(File),
    findall(macrop(Id, Name, Fields, hits(H)),
            ( stored(File, Id, Name, Fields), stored_hits(File, Id, H) ),
            Macrops).

%!  stored_hits(+File, +Id, -Hits:integer) is det.
%
%   Hits is the number of lookups MACROP Id of store File answered.

stored_hits(File, Id, Hits) :-
    hit_key(File, Id, Key),
    flag(Key, Hits, Hits).

%!  store_counts(+File, -Lookups:integer, -Hits:integer, -Misses:integer) is det.
%
%   The lookups made in store File and how many found a MACROP (hand-written ones
%   included) and how many did not.

store_counts(File, Lookups, Hits, Misses) :-
    must_be_open(File),
    count_base(File, MissKey, Lookups0, Hits0, Misses0),
    aggregate_all(sum(H - H0),
                  ( counted(File, Id, H0), stored_hits(File, Id, H) ),
                  NewHits),
    flag(MissKey, NewMisses, NewMisses),
    Lookups is Lookups0 + NewHits + NewMisses,
    Hits is Hits0 + NewHits,
    Misses is Misses0 + NewMisses.

%!  store_macrop(+File, +NameAndFormat, +Fields, -Stored) is det.
%
%   Store a MACROP in the open store File: Stored is `new(Id)`, stored under the next
%   number Id, or `existing(Id)` when a variant of it is there already as Id (nothing
%   stored).

store_macrop(File, Name, Fields, Stored) :-
    must_be_open(File),
    (   stored(File, Id0, Name0, Fields0),
        macrop(Name0, Fields0) =@= macrop(Name, Fields)
    ->  Stored = existing(Id0)
    ;   (   aggregate_all(max(I), stored(File, I, _, _), Max)
        ->  Id is Max + 1
        ;   Id = 1
        ),
        assertz(stored(File, Id, Name, Fields)),
        Stored = new(Id)
    ).

%!  count_lookup(+File, +Found) is det.
%
%   Count a lookup in store File: `hit(Id)` (MACROP Id answered it) or `miss`.

count_lookup(File, hit(Id)) :- !,
    hit_key(File, Id, Key),
    count_hit(File, Id, Key).
count_lookup(File, miss) :-
    count_base(File, MissKey, _, _, _),
    flag(MissKey, M, M + 1).

%!  count_hit(+File, +Id, +Key) is det.
%
%   Count a hit of MACROP Id of store File on its flag Key (hit_key/3).

count_hit(File, Id, Key) :-
    flag(Key, N, N + 1),
    (   N == 0,
        \+ counted(File, Id, _)
    ->  assertz(counted(File, Id, 0))
    ;   true
    ).
