defmodule Neptunus.Test.Cluster do
  @moduledoc """
  Multi-node tests on one machine with OTP's `:peer`: the test node becomes distributed
  (`distribute!/0`), and each peer is a second Neptunus node with its own vehicles and its
  own HTTP/WebSocket port (`start_node!/3`).

  A peer is controlled over its standard input/output (`connection: :standard_io`), not
  over distribution, so a test can cut the distribution link between the nodes
  (`partition!/1`: the peer refuses every node, then the test node drops the connection)
  and still drive the peer, then heal it (`heal!/1`).

  `Neptunus.Test.Cluster.Collector` runs on a peer and keeps the broadcasts of a topic there,
  for a test to read what the peer's node saw while it was cut off.
  """

  import ExUnit.Assertions

  @type peer :: %{pid: pid(), node: node(), port: :inet.port_number()}

  @doc "Makes the test node distributed (once per test run), named after its HTTP port."
  @spec distribute!() :: node()
  def distribute! do
    unless Node.alive?() do
      port = Application.fetch_env!(:neptunus, :endpoint).port
      name = :"neptunus_test_#{port}@127.0.0.1"
      {:ok, _} = :net_kernel.start(name, %{name_domain: :longnames})
    end

    node()
  end

  @doc """
  Starts a Neptunus node `name` (`name@127.0.0.1`) serving on `port` with `vehicles`
  (`[%{id, board}]`, `[]` for a relay node), connected to the test node. The test node's
  application settings are copied, but for the port, the vehicles and `env` (application
  settings of the peer's own).
  """
  @spec start_node!(atom(), :inet.port_number(), [map()], keyword()) :: peer()
  def start_node!(name, port, vehicles, env \\ []) do
    distribute!()
    paths = Enum.flat_map(:code.get_path(), &[~c"-pa", &1])

    {:ok, pid, node} =
      :peer.start(%{
        name: name,
        host: ~c"127.0.0.1",
        longnames: true,
        connection: :standard_io,
        args: [~c"-setcookie", Atom.to_charlist(Node.get_cookie()) | paths]
      })

    env =
      Application.get_all_env(:neptunus)
      |> Keyword.merge(cluster: nil, vehicles: vehicles)
      |> Keyword.merge(env)
      |> Keyword.update!(:endpoint, &%{&1 | port: port})

    call(%{pid: pid}, Application, :load, [:neptunus])
    for {key, value} <- env, do: call(%{pid: pid}, Application, :put_env, [:neptunus, key, value])
    call(%{pid: pid}, Application, :put_env, [:logger, :level, :warning])
    {:ok, _} = call(%{pid: pid}, Application, :ensure_all_started, [:neptunus])
    true = Node.connect(node)
    peer = %{pid: pid, node: node, port: port}

    for %{id: id} <- vehicles, do: await_located!(id, node)
    peer
  end

  @doc """
  Stops the peer node (as if it crashed: no goodbye to the cluster), and makes the test
  node's directory forget its vehicles (they would be listed as unreachable to the tests
  that follow, and a page opens the first vehicle listed).
  """
  @spec stop_node(peer()) :: :ok
  def stop_node(%{pid: pid, node: node}) do
    try do
      :peer.stop(pid)
    catch
      :exit, _ -> :ok
    end

    wait!(fn -> node not in Node.list() end, "#{node} down")
    Neptunus.Fleet.Directory.sync()
    Neptunus.Fleet.Directory.forget(node)
  end

  @doc "Runs `module.fun(args)` on the peer (over its control connection)."
  @spec call(%{pid: pid()}, module(), atom(), list()) :: term()
  def call(%{pid: pid}, module, fun, args), do: :peer.call(pid, module, fun, args, 15_000)

  @doc "Cuts distribution between the test node and `peer`, and keeps it cut."
  @spec partition!(peer()) :: :ok
  def partition!(peer) do
    # the peer allows no node from now on (nor reconnections from either side)...
    :ok = call(peer, :net_kernel, :allow, [[:"nobody@127.0.0.1"]])
    # ...and the test node drops the link
    true = :erlang.disconnect_node(peer.node)
    refute peer.node in Node.list()
    :ok
  end

  @doc "Lets `peer` and the test node connect again, and connects them."
  @spec heal!(peer()) :: :ok
  def heal!(peer) do
    :ok = call(peer, :net_kernel, :allow, [[node()]])
    assert Node.connect(peer.node)
    :ok
  end

  @doc "Waits until this node's directory places vehicle `id` on `node` (5 s at most)."
  @spec await_located!(String.t(), node()) :: :ok
  def await_located!(id, node) do
    wait!(fn -> match?({:ok, ^node, _}, Neptunus.Fleet.locate(id)) end, "#{id} on #{node}")
  end

  @doc "Waits until `fun` returns true, polling every 20 ms (`timeout` ms at most)."
  @spec wait!((() -> boolean()), String.t(), pos_integer()) :: :ok
  def wait!(fun, what, timeout \\ 5_000) do
    deadline = System.monotonic_time(:millisecond) + timeout
    do_wait(fun, what, deadline)
  end

  defp do_wait(fun, what, deadline) do
    cond do
      fun.() ->
        :ok

      System.monotonic_time(:millisecond) > deadline ->
        flunk("timed out waiting for #{what}")

      true ->
        Process.sleep(20)
        do_wait(fun, what, deadline)
    end
  end

  defmodule Collector do
    @moduledoc """
    Keeps every broadcast of a topic on its node (a term subscriber), to be read with
    `events/1`. Started on a peer with `Neptunus.Test.Cluster.call/4`.
    """
    use GenServer

    @spec start(String.t()) :: {:ok, pid()}
    def start(topic), do: GenServer.start(__MODULE__, topic)

    @doc "The broadcasts so far, oldest first: `[{event, payload}]`."
    @spec events(pid()) :: [{String.t(), map()}]
    def events(pid), do: GenServer.call(pid, :events)

    @impl true
    def init(topic) do
      :ok = Neptunus.PubSub.subscribe(topic)
      {:ok, []}
    end

    @impl true
    def handle_call(:events, _from, events), do: {:reply, Enum.reverse(events), events}

    @impl true
    def handle_info({:pubsub, _topic, event, payload}, events),
      do: {:noreply, [{event, payload} | events]}
  end

  defmodule SendTracer do
    @moduledoc """
    Traces the messages a process sends (`:erlang.trace/3`, on the process' node) and keeps
    the distinct receivers on other nodes, to show what crosses the node boundary.
    Started on a peer with `Neptunus.Test.Cluster.call/4`.
    """
    use GenServer

    @spec start(pid()) :: {:ok, pid()}
    def start(traced), do: GenServer.start(__MODULE__, traced)

    @doc "The receivers on other nodes so far, and how many messages went to each."
    @spec remote_receivers(pid()) :: %{pid() => pos_integer()}
    def remote_receivers(pid), do: GenServer.call(pid, :receivers)

    @impl true
    def init(traced) do
      1 = :erlang.trace(traced, true, [:send, {:tracer, self()}])
      {:ok, %{}}
    end

    @impl true
    def handle_call(:receivers, _from, seen), do: {:reply, seen, seen}

    @impl true
    def handle_info({:trace, _from, :send, _msg, to}, seen)
        when is_pid(to) and node(to) != node(),
        do: {:noreply, Map.update(seen, to, 1, &(&1 + 1))}

    def handle_info(_other, seen), do: {:noreply, seen}
  end
end
