:- use_module(macrop_store).

/*  Tests of the MACROP store: a file of learned MACROPs with their lookup counts.  */

store_file(File) :-
    tmp_file(macrop_store, Base),
    atom_concat(Base, '.pl', File).

macrop_one(m(A, B), [purpose([g(A)]), plan([step(1, act(A, B), [])])]).

:- begin_tests(store).

test(saved_and_loaded_with_its_hits, true(X = [1, [macrop(1, m(_, _), _, hits(2))], c(3, 2, 1)])) :-
    store_file(File),
    load_store(File),
    macrop_one(N, F),
    store_macrop(File, N, F, new(Id)),
    hit_key(File, Id, Key),
    count_hit(File, Id, Key),
    count_lookup(File, hit(Id)),
    count_lookup(File, miss),
    save_store(File),
    forget_store(File),
    load_store(File),
    store_macrops(File, Ms),
    store_counts(File, L, H, M),
    forget_store(File),
    delete_file(File),
    X = [Id, Ms, c(L, H, M)].

test(a_variant_is_not_stored_twice, true(Stored-N == existing(1)-1)) :-
    store_file(File),
    load_store(File),
    macrop_one(N1, F1),
    store_macrop(File, N1, F1, _),
    macrop_one(N2, F2),
    store_macrop(File, N2, F2, Stored),
    aggregate_all(count, stored(File, _, _, _), N),
    forget_store(File).

test(reset_forgets_and_changes_the_generation, true(X == [0, c(0, 0, 0), changed])) :-
    store_file(File),
    load_store(File),
    store_generation(File, G0),
    macrop_one(N, F),
    store_macrop(File, N, F, _),
    count_lookup(File, miss),
    reset_store(File),
    store_generation(File, G1),
    aggregate_all(count, stored(File, _, _, _), K),
    store_counts(File, L, H, M),
    forget_store(File),
    ( G1 \== G0 -> Changed = changed ; Changed = same ),
    X = [K, c(L, H, M), Changed].

test(a_term_that_is_no_store_term, error(domain_error(macrop_store_term(_), hello(world)))) :-
    store_file(File),
    setup_call_cleanup(open(File, write, Out), format(Out, "hello(world).~n", []), close(Out)),
    call_cleanup(load_store(File), delete_file(File)).

test(not_open, error(existence_error(macrop_store, '/nonexistent/y.pl'))) :-
    store_counts('/nonexistent/y.pl', _, _, _).

% A full disk (the temporary file a link to /dev/full): the error names the store's file
% and the system's reason, the temporary file is gone and the store's file is as it was.
test(a_full_disk_names_the_file_and_leaves_no_temporary_file,
     [ condition(access_file('/dev/full', exist)),
       true(X == [File, 'No space left on device', false, kept])
     ]) :-
    store_file(File),
    setup_call_cleanup(open(File, write, Out0), format(Out0, "store_counts(0, 0, 0).~n", []), close(Out0)),
    load_store(File),
    macrop_one(N, F),
    store_macrop(File, N, F, _),
    atom_concat(File, '.tmp', Tmp),
    link_file('/dev/full', Tmp, symbolic),
    catch(save_store(File), error(macrop_store_write(Named, Reason), _), true),
    forget_store(File),
    ( exists_file(Tmp) -> Left = true ; read_link(Tmp, _, _) -> Left = true ; Left = false ),
    read_file_to_terms(File, Terms, []),
    ( Terms == [store_counts(0, 0, 0)] -> Kept = kept ; Kept = changed ),
    delete_file(File),
    X = [Named, Reason, Left, Kept].

:- end_tests(store).
