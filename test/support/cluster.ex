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
      # a node started at run time does not start epmd (`erl -name` would): another test's
      # peer may have, or not
      {_, 0} = System.cmd("epmd", ["-daemon"])
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
    peer = start_peer!(name, port, vehicles, env, host: "127.0.0.1", cookie: Node.get_cookie())
    true = Node.connect(peer.node)

    for %{id: id} <- vehicles, do: await_located!(id, peer.node)
    peer
  end

  @doc """
  Starts a Neptunus node `name@host` serving on `port` with `vehicles` and the application
  settings `env` (over the test node's), controlled over its standard input/output and not
  connected to the test node. `opts`: `host`, `cookie` (atom), `exec` (`{program, args}`
  that starts `erl`: e.g. in a network namespace), `args` (more VM arguments).
  """
  @spec start_peer!(atom(), :inet.port_number(), [map()], keyword(), keyword()) :: peer()
  def start_peer!(name, port, vehicles, env, opts) do
    paths = Enum.flat_map(:code.get_path(), &[~c"-pa", &1])
    cookie = Keyword.fetch!(opts, :cookie)
    args = Enum.map(Keyword.get(opts, :args, []), &String.to_charlist/1)

    options = %{
      name: name,
      host: String.to_charlist(Keyword.fetch!(opts, :host)),
      longnames: true,
      connection: :standard_io,
      # the cookie is set once the node runs, not with -setcookie: erl reads an argument
      # starting with "+" as an emulator flag (a base64 cookie does, one time in 64)
      args: args ++ paths
    }

    options =
      case Keyword.get(opts, :exec) do
        nil ->
          options

        {program, exec_args} ->
          Map.put(
            options,
            :exec,
            {String.to_charlist(program), Enum.map(exec_args, &String.to_charlist/1)}
          )
      end

    {:ok, pid, node} = :peer.start(options)
    true = call(%{pid: pid}, :erlang, :set_cookie, [cookie])

    env =
      Application.get_all_env(:neptunus)
      |> Keyword.merge(cluster: nil, vehicles: vehicles)
      |> Keyword.merge(env)
      |> Keyword.update!(:endpoint, &%{&1 | port: port})

    call(%{pid: pid}, Application, :load, [:neptunus])
    for {key, value} <- env, do: call(%{pid: pid}, Application, :put_env, [:neptunus, key, value])
    call(%{pid: pid}, Application, :put_env, [:logger, :level, :warning])
    {:ok, _} = call(%{pid: pid}, Application, :ensure_all_started, [:neptunus])
    %{pid: pid, node: node, port: port}
  end

  @doc """
  Stops the peer node (as if it crashed: no goodbye to the cluster), and makes the test
  node's directory forget its vehicles (they would be listed as unreachable to the tests
  that follow, and a page opens the first vehicle listed).
  """
  @spec stop_node(peer()) :: :ok
  def stop_node(%{node: node} = peer) do
    stop_peer(peer)
    wait!(fn -> node not in Node.list() end, "#{node} down")
    Neptunus.Fleet.Directory.sync()
    Neptunus.Fleet.Directory.forget(node)
  end

  @doc "Stops a peer node (started by `start_peer!/5`), if it still runs."
  @spec stop_peer(peer()) :: :ok
  def stop_peer(%{pid: pid}) do
    :peer.stop(pid)
  catch
    :exit, _ -> :ok
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

  @doc "Waits until this node's directory places vehicle `id` on `node` (`Neptunus.Test.Patience`)."
  @spec await_located!(String.t(), node()) :: :ok
  def await_located!(id, node) do
    wait!(fn -> match?({:ok, ^node, _}, Neptunus.Fleet.locate(id)) end, "#{id} on #{node}")
  end

  @doc """
  Waits until `fun` returns true, polling every 20 ms (`timeout` ms at most,
  `Neptunus.Test.Patience`).
  """
  @spec wait!((() -> boolean()), String.t(), pos_integer()) :: :ok
  def wait!(fun, what, timeout \\ Neptunus.Test.Patience.ms()) do
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

  defmodule Pilot do
    @moduledoc """
    A browser's connection on a peer's node, seen from the test: a WebSocket client to the
    peer's own endpoint (`127.0.0.1`, in the peer's network namespace if it has one) that
    joins a vehicle's topic and keeps every frame the server pushes. Started on the peer
    with `Neptunus.Test.Cluster.call/4`; `push/3` waits for the reply, `drive/2` sends a
    thrust and a heartbeat every 100 ms with a grant's epoch, as a pilot's page does.
    """
    use GenServer

    alias NeptunusWeb.Test.WSClient

    @type t :: %__MODULE__{
            ws: pid(),
            topic: String.t(),
            join_ref: String.t(),
            events: [{String.t(), map()}],
            epoch: integer() | nil
          }
    defstruct [:ws, :topic, :join_ref, :epoch, events: []]

    @spec start(:inet.port_number(), String.t(), String.t()) :: {:ok, pid()}
    def start(port, topic, name), do: GenServer.start(__MODULE__, {port, topic, name})

    @doc "Pushes `event` and returns `{status, response}` of its reply."
    @spec push(pid(), String.t(), map()) :: {String.t(), map()}
    def push(pid, event, payload), do: GenServer.call(pid, {:push, event, payload}, 10_000)

    @doc "Sends a thrust (surge 0.5) and a heartbeat every 100 ms with `epoch`; nil stops."
    @spec drive(pid(), integer() | nil) :: :ok
    def drive(pid, epoch), do: GenServer.call(pid, {:drive, epoch})

    @doc "The events the server pushed so far, oldest first: `[{event, payload}]`."
    @spec events(pid()) :: [{String.t(), map()}]
    def events(pid), do: GenServer.call(pid, :events)

    @impl true
    def init({port, topic, name}) do
      query = URI.encode_query(%{"vsn" => "2.0.0", "name" => name})
      {:ok, ws} = WSClient.connect(port, "/socket/websocket?" <> query)
      join_ref = WSClient.unique_ref()
      {:ok, _snapshot} = WSClient.join(ws, topic, %{}, join_ref)
      {:ok, %__MODULE__{ws: ws, topic: topic, join_ref: join_ref}}
    end

    @impl true
    def handle_call({:push, event, payload}, _from, state) do
      ref = WSClient.unique_ref()
      :ok = WSClient.push(state.ws, state.join_ref, ref, state.topic, event, payload)
      {reply, state} = await_reply(state, ref, System.monotonic_time(:millisecond) + 5_000)
      {:reply, reply, state}
    end

    def handle_call({:drive, epoch}, _from, state) do
      if epoch != nil and state.epoch == nil, do: send(self(), :drive)
      {:reply, :ok, %{state | epoch: epoch}}
    end

    def handle_call(:events, _from, state), do: {:reply, Enum.reverse(state.events), state}

    @impl true
    def handle_info(:drive, %__MODULE__{epoch: nil} = state), do: {:noreply, state}

    def handle_info(:drive, state) do
      thrust = %{
        "mode" => "motion",
        "surge" => 0.5,
        "heave" => 0,
        "yaw" => 0,
        "epoch" => state.epoch
      }

      WSClient.push(
        state.ws,
        state.join_ref,
        WSClient.unique_ref(),
        state.topic,
        "thrust",
        thrust
      )

      WSClient.push(
        state.ws,
        state.join_ref,
        WSClient.unique_ref(),
        state.topic,
        "heartbeat",
        %{}
      )

      Process.send_after(self(), :drive, 100)
      {:noreply, state}
    end

    def handle_info({:ws, ws, {:text, text}}, %__MODULE__{ws: ws} = state),
      do: {:noreply, record(state, decode(text))}

    def handle_info(_other, state), do: {:noreply, state}

    defp await_reply(state, ref, deadline) do
      ws = state.ws

      receive do
        {:ws, ^ws, {:text, text}} ->
          case decode(text) do
            [_, ^ref, _, "phx_reply", %{"status" => status, "response" => response}] ->
              {{status, response}, state}

            frame ->
              await_reply(record(state, frame), ref, deadline)
          end
      after
        max(deadline - System.monotonic_time(:millisecond), 0) ->
          {{"timeout", %{}}, state}
      end
    end

    defp decode(text), do: :jiffy.decode(text, [:return_maps, {:null_term, nil}])

    defp record(state, [_, nil, _, event, payload]),
      do: %{state | events: [{event, payload} | state.events]}

    defp record(state, _reply), do: state
  end

  defmodule Netns do
    @moduledoc """
    Linux network namespaces for a partition by cutting a link (root and `ip netns`): two
    namespaces joined by a veth pair, each end with its address; `cut/2` and `heal/2` set
    one end down and up. `cleanup/1` kills what still runs in them (the peers' port
    mappers, epmd, outlive their node) and deletes them.
    """

    @type pair :: %{
            ns: {String.t(), String.t()},
            ifs: {String.t(), String.t()},
            addrs: {String.t(), String.t()}
          }

    @doc "nil when namespaces can be made here, else why not."
    @spec unavailable() :: String.t() | nil
    def unavailable do
      probe = "nxprobe#{System.unique_integer([:positive])}"

      cond do
        :os.type() != {:unix, :linux} ->
          "not Linux"

        System.find_executable("ip") == nil ->
          "the ip command (iproute2) is not installed"

        System.find_executable("openssl") == nil ->
          "openssl is not installed (the test makes TLS certificates)"

        true ->
          case System.cmd("ip", ["netns", "add", probe], stderr_to_stdout: true) do
            {_, 0} ->
              System.cmd("ip", ["netns", "del", probe], stderr_to_stdout: true)
              nil

            {out, _} ->
              "`ip netns add` fails (root needed): #{String.trim(out)}"
          end
      end
    end

    @doc """
    Makes namespaces `<prefix>a` and `<prefix>b` joined by veth `<prefix>a`/`<prefix>b`,
    addresses `10.<n>.<m>.1` and `.2` (/30), loopback and both ends up.
    """
    @spec setup!(String.t(), {0..255, 0..255}) :: pair()
    def setup!(prefix, {n, m}) do
      {na, nb} = {prefix <> "a", prefix <> "b"}
      {ia, ib} = {prefix <> "a", prefix <> "b"}
      {aa, ab} = {"10.#{n}.#{m}.1", "10.#{n}.#{m}.2"}

      for args <- [
            ~w(netns add #{na}),
            ~w(netns add #{nb}),
            ~w(link add #{ia} type veth peer name #{ib}),
            ~w(link set #{ia} netns #{na}),
            ~w(link set #{ib} netns #{nb}),
            ~w(-n #{na} addr add #{aa}/30 dev #{ia}),
            ~w(-n #{nb} addr add #{ab}/30 dev #{ib}),
            ~w(-n #{na} link set lo up),
            ~w(-n #{nb} link set lo up),
            ~w(-n #{na} link set #{ia} up),
            ~w(-n #{nb} link set #{ib} up)
          ],
          do: ip!(args)

      %{ns: {na, nb}, ifs: {ia, ib}, addrs: {aa, ab}}
    end

    @doc "Sets the veth end in namespace `ns` down: nothing passes the link any more."
    @spec cut!(pair(), :a | :b) :: :ok
    def cut!(pair, side), do: link!(pair, side, "down")

    @doc "Sets it up again."
    @spec heal!(pair(), :a | :b) :: :ok
    def heal!(pair, side), do: link!(pair, side, "up")

    defp link!(%{ns: {na, nb}, ifs: {ia, ib}}, side, state) do
      {ns, ifname} = if side == :a, do: {na, ia}, else: {nb, ib}
      ip!(~w(-n #{ns} link set #{ifname} #{state}))
      :ok
    end

    @doc "Kills every process left in the namespaces (by pid) and deletes them."
    @spec cleanup(pair() | String.t()) :: :ok
    def cleanup(%{ns: {na, nb}}), do: Enum.each([na, nb], &cleanup/1)

    def cleanup(ns) when is_binary(ns) do
      {pids, _} = System.cmd("ip", ["netns", "pids", ns], stderr_to_stdout: true)

      for pid <- String.split(pids),
          pid =~ ~r/\A\d+\z/,
          do: System.cmd("kill", ["-9", pid], stderr_to_stdout: true)

      System.cmd("ip", ["netns", "del", ns], stderr_to_stdout: true)
      :ok
    end

    @doc "`{program, args}` that runs `erl` in namespace `ns` (the `exec` of a peer)."
    @spec erl_in(String.t()) :: {String.t(), [String.t()]}
    def erl_in(ns),
      do: {System.find_executable("ip"), ["netns", "exec", ns, System.find_executable("erl")]}

    @doc """
    A throwaway CA and one node certificate it signs (valid for `addresses`, as IP and as
    name: the TLS client checks the node name's host) in `dir`: `%{certfile, keyfile,
    cacertfile}`.
    """
    @spec certificates!(Path.t(), [String.t()]) :: %{
            certfile: String.t(),
            keyfile: String.t(),
            cacertfile: String.t()
          }
    def certificates!(dir, addresses) do
      File.mkdir_p!(dir)
      f = &Path.join(dir, &1)
      san = Enum.map_join(addresses, ",", &"IP:#{&1},DNS:#{&1}")
      File.write!(f.("ext"), "subjectAltName=#{san}\n")

      openssl!(
        ~w(req -x509 -newkey rsa:2048 -nodes -days 1 -subj /CN=neptunus-test-ca) ++
          ["-keyout", f.("ca.key"), "-out", f.("ca.pem")]
      )

      openssl!(
        ~w(req -newkey rsa:2048 -nodes -subj /CN=neptunus-test-node) ++
          ["-keyout", f.("node.key"), "-out", f.("node.csr")]
      )

      openssl!(
        ~w(x509 -req -days 1 -CAcreateserial) ++
          [
            "-in",
            f.("node.csr"),
            "-CA",
            f.("ca.pem"),
            "-CAkey",
            f.("ca.key"),
            "-out",
            f.("node.pem"),
            "-extfile",
            f.("ext")
          ]
      )

      %{certfile: f.("node.pem"), keyfile: f.("node.key"), cacertfile: f.("ca.pem")}
    end

    defp openssl!(args) do
      {out, status} = System.cmd("openssl", args, stderr_to_stdout: true)
      status == 0 || raise "openssl #{Enum.join(args, " ")} failed: #{out}"
    end

    defp ip!(args) do
      {out, status} = System.cmd("ip", args, stderr_to_stdout: true)
      status == 0 || raise "ip #{Enum.join(args, " ")} failed: #{out}"
    end
  end
end
