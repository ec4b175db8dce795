%% The soak's server-side probe (bench/soak, bench/soak.mjs): run on a hidden node, it loads
%% itself into the server's node (once) and reports, as one line of JSON on stdout, where the server's
%% memory is:
%%
%%   * process count and the two longest message queues (and whose);
%%   * erlang:memory() by type (total, processes, processes_used, system, binary, ets, code,
%%     atom), in bytes, and the processes' live data (`processes_live`: the heap words in use,
%%     not the heap blocks);
%%   * the allocators' carriers (what the VM holds from the OS) and the blocks in them (what is
%%     in use), summed over every alloc_util allocator and instance (mbcs + sbcs), so that RSS
%%     can be told apart from live data;
%%   * the 5 largest processes by `memory`, each with its name or initial call, its heap, its
%%     message queue and the refc binary bytes it references (process_info(P, binary) summed);
%%   * the vehicle recorder's and telemetry's state sizes (erts_debug:flat_size of sys:get_state,
%%     in bytes, shared binaries counted by their header only) and process memory.
%%
%% Usage: erl -hidden -noshell -sname NAME -setcookie COOKIE -pa DIR
%%            -eval 'soak_probe:main()' -- SERVER_NODE [stats|gc]
%% `gc` first garbage-collects every process of the server (erlang:garbage_collect/1) and
%% reports the figures after it, with `gc_before_total` (erlang:memory(total) before): memory
%% that a full collection gives back was garbage, what stays is live data.
-module(soak_probe).
-export([main/0, collect/1]).

main() ->
    Args = init:get_plain_arguments(),
    {NodeName, Mode} =
        case Args of
            [N] -> {N, stats};
            [N, M] -> {N, list_to_atom(M)}
        end,
    Node = list_to_atom(NodeName),
    Out =
        try
            ok = load(Node),
            case rpc:call(Node, ?MODULE, collect, [Mode], 60000) of
                {badrpc, R} -> #{error => fmt("~p", [R])};
                Map -> Map
            end
        catch
            C:E -> #{error => fmt("~p:~p", [C, E])}
        end,
    io:format("~n~s~n", [json(Out)]),
    halt().

%% Loads this module into the server's node unless the same version is there already (loading
%% it again would make the node purge the old one at every row).
load(Node) ->
    Md5 = ?MODULE:module_info(md5),
    case rpc:call(Node, ?MODULE, module_info, [md5], 30000) of
        Md5 -> ok;
        _ ->
            {Mod, Bin, File} = code:get_object_code(?MODULE),
            {module, Mod} = rpc:call(Node, code, load_binary, [Mod, File, Bin], 30000),
            ok
    end.

%% On the server's node.
collect(Mode) ->
    Before = erlang:memory(total),
    GcMs =
        case Mode of
            gc ->
                T0 = erlang:monotonic_time(millisecond),
                [erlang:garbage_collect(P) || P <- erlang:processes()],
                erlang:monotonic_time(millisecond) - T0;
            stats ->
                0
        end,
    Procs = [P || P <- erlang:processes(), P =/= self()],
    Infos = lists:filtermap(
        fun(P) ->
            case erlang:process_info(P, [memory, message_queue_len, total_heap_size,
                                         garbage_collection_info,
                                         registered_name, dictionary, initial_call]) of
                undefined -> false;
                I -> {true, {P, I}}
            end
        end, Procs),
    Queues = lists:sublist(
        lists:reverse(lists:keysort(1, [{get(message_queue_len, I), P, I} || {P, I} <- Infos])), 2),
    Largest = lists:sublist(
        lists:reverse(lists:keysort(1, [{get(memory, I), P, I} || {P, I} <- Infos])), 5),
    Mem = maps:from_list([{K, V} || {K, V} <- erlang:memory(),
                                    lists:member(K, [total, processes, processes_used, system,
                                                     atom, binary, code, ets])]),
    {Carriers, Blocks} = allocated(),
    #{procs => erlang:system_info(process_count),
      memory => Mem,
      processes_live => lists:sum([live_bytes(I) || {_, I} <- Infos]),
      mode => Mode,
      gc_before_total => Before,
      gc_ms => GcMs,
      carriers => Carriers,
      blocks => Blocks,
      queues => [#{len => L, who => who(P, I)} || {L, P, I} <- Queues],
      largest => [#{who => who(P, I), memory => M,
                    heap => 8 * get(total_heap_size, I),
                    queue => get(message_queue_len, I),
                    binary => binary_bytes(P)} || {M, P, I} <- Largest],
      states => [state_size(Name, Mod, Infos) || {Name, Mod} <- [{recorder, 'Elixir.Neptunus.Vehicle.Recorder'},
                                                                 {telemetry, 'Elixir.Neptunus.Vehicle.Telemetry'}]]}.

get(K, I) -> proplists:get_value(K, I).

%% The words a process' data takes (young and old heap in use, heap fragments, stack), in
%% bytes: unlike `memory`, not the heap blocks' size, which after a GC depends on the heap's
%% size before it (three full GCs in a row give process memory totals ±50 % apart).
live_bytes(I) ->
    G = get(garbage_collection_info, I),
    8 * lists:sum([proplists:get_value(K, G, 0) || K <- [heap_size, old_heap_size, mbuf_size, stack_size]]).

%% The refc binaries a process references, in bytes.
binary_bytes(P) ->
    case erlang:process_info(P, binary) of
        {binary, Bins} -> lists:sum([Size || {_, Size, _} <- Bins]);
        undefined -> 0
    end.

%% The first process started with Mod:init/1 (a GenServer): its state's size and memory.
state_size(Name, Mod, Infos) ->
    case [P || {P, I} <- Infos, initial(I) =:= {Mod, init, 1}] of
        [] -> #{name => Name, found => false};
        [P | _] ->
            Words = try erts_debug:flat_size(sys:get_state(P, 5000)) catch _:_ -> -1 end,
            #{name => Name, found => true, state => 8 * Words,
              memory => element(2, erlang:process_info(P, memory)), binary => binary_bytes(P)}
    end.

initial(I) ->
    case proplists:get_value('$initial_call', get(dictionary, I)) of
        {_, _, _} = MFA -> MFA;
        _ -> get(initial_call, I)
    end.

who(P, I) ->
    case get(registered_name, I) of
        [] -> {M, F, A} = initial(I), fmt("~p (~s:~s/~b)", [P, M, F, A]);
        Name -> atom_to_list(Name)
    end.

%% What the allocators hold from the OS (carriers) and use of it (blocks), in bytes: summed
%% over every alloc_util allocator's instances, multiblock and singleblock carriers.
allocated() ->
    lists:foldl(
        fun(A, Acc) ->
            case erlang:system_info({allocator, A}) of
                L when is_list(L) ->
                    lists:foldl(fun({instance, _, Props}, {C, B}) ->
                                        {C1, B1} = carrier_sums(Props),
                                        {C + C1, B + B1};
                                   (_, CB) -> CB
                                end, Acc, L);
                _ -> Acc
            end
        end, {0, 0}, erlang:system_info(alloc_util_allocators)).

carrier_sums(Props) ->
    lists:foldl(
        fun(Kind, {C, B}) ->
            case proplists:get_value(Kind, Props) of
                undefined -> {C, B};
                K ->
                    Cs = case lists:keyfind(carriers_size, 1, K) of
                             {carriers_size, Cur, _, _} -> Cur;
                             _ -> 0
                         end,
                    Bs = lists:sum([Cur || {_, Types} <- proplists:get_value(blocks, K, []),
                                           {size, Cur, _, _} <- Types]),
                    {C + Cs, B + Bs}
            end
        end, {0, 0}, [mbcs, sbcs]).

fmt(F, A) -> lists:flatten(io_lib:format(F, A)).

%% A small JSON encoder for the probe's own terms.
json(M) when is_map(M) ->
    ["{", lists:join(",", [[json(atom_to_list(K)), ":", json(V)] || {K, V} <- lists:sort(maps:to_list(M))]), "}"];
json(true) -> "true";
json(false) -> "false";
json(A) when is_atom(A) -> json(atom_to_list(A));
json(N) when is_integer(N) -> integer_to_list(N);
json(F) when is_float(F) -> float_to_list(F, [{decimals, 3}]);
json(L) when is_list(L) ->
    case io_lib:printable_unicode_list(L) of
        true -> [$", [esc(C) || C <- L], $"];
        false -> ["[", lists:join(",", [json(X) || X <- L]), "]"]
    end.

esc($") -> "\\\"";
esc($\\) -> "\\\\";
esc(C) when C < 32 -> "?";
esc(C) -> C.
