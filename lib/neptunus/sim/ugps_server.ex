defmodule Neptunus.Sim.UGPSServer do
  @moduledoc """
  The simulated Underwater GPS topside as a device on the network: an HTTP/1.1 server on
  loopback answering the parts of the Water Linked API a vehicle uses
  (`Neptunus.Protocol.UnderwaterGPS`), so the real driver (`Neptunus.Position.UGPS`) is what
  reads a simulated vehicle's USBL.

    * `GET /api/v1/position/acoustic/filtered` — the latest fix of the `Neptunus.Sim.USBL`
      it steps with the vehicle's simulated pose (`Neptunus.Camera.Pose`); with no pose for
      2 s (the simulator paused or stopped) a fix with `position_valid: false`;
    * `PUT /api/v1/external/depth` — the vehicle's depth and the water temperature, checked
      as the API specifies (400 with the reason otherwise); the simulated system needs it for
      a valid fix, as a Locator-A1 system does;
    * anything else — 404.

  Connections are kept alive (`:httpc` reuses them); each is served by its own process,
  which asks this server for the fix or gives it the depth.

  Options: `:id`, `:name`, `:port` (default 0: any; `url/2` tells the base URL), `:usbl`
  (`Neptunus.Sim.USBL` settings), `:seed`.
  """
  use GenServer

  alias Neptunus.Camera.Pose
  alias Neptunus.PubSub.Follow
  alias Neptunus.Protocol.UnderwaterGPS
  alias Neptunus.Sim.USBL

  @stale_pose_s 2.0
  @max_body 4096

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{}
    defstruct [:id, :listen, :port, :usbl, :fix, :pose_at, :follow]
  end

  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts) do
    GenServer.start_link(__MODULE__, opts,
      name: via(Keyword.fetch!(opts, :id), Keyword.get(opts, :name, :usbl))
    )
  end

  @doc "The base URL of vehicle `id`'s simulated topside (source `name`)."
  @spec url(String.t(), atom()) :: String.t()
  def url(id, name), do: "http://127.0.0.1:#{GenServer.call(via(id, name), :port)}"

  defp via(id, name), do: Neptunus.Fleet.via({__MODULE__, name}, id)

  # Callbacks

  @impl true
  def init(opts) do
    listen_opts = [:binary, active: false, reuseaddr: true, ip: {127, 0, 0, 1}, packet: :http_bin]
    {:ok, listen} = :gen_tcp.listen(Keyword.get(opts, :port, 0), listen_opts)
    {:ok, port} = :inet.port(listen)
    server = self()
    spawn_link(fn -> accept(listen, server) end)
    seed = Keyword.get(opts, :seed, :erlang.unique_integer([:positive]))
    usbl = USBL.new(Keyword.get(opts, :usbl, []), seed)
    state = %State{id: Keyword.fetch!(opts, :id), listen: listen, port: port, usbl: usbl}
    {:ok, state, {:continue, :subscribe}}
  end

  @impl true
  def handle_continue(:subscribe, state) do
    {_subscribed_or_waiting, follow} = Follow.subscribe(Follow.new([Pose.topic(state.id)]))
    {:noreply, %{state | follow: follow}}
  end

  @impl true
  def handle_call(:port, _from, state), do: {:reply, state.port, state}

  def handle_call(:fix, _from, state) do
    fix =
      cond do
        state.fix == nil ->
          invalid()

        state.pose_at == nil or now() - state.pose_at > @stale_pose_s ->
          %{state.fix | valid: false}

        true ->
          state.fix
      end

    {:reply, fix, state}
  end

  def handle_call({:depth, depth, temp}, _from, state),
    do: {:reply, :ok, %{state | usbl: USBL.depth(state.usbl, now(), {depth, temp})}}

  @impl true
  def handle_info({:pubsub, _topic, "pose", pose}, state) do
    t = now()
    {fixes, usbl} = USBL.step(state.usbl, t, pose)
    {:noreply, %{state | usbl: usbl, fix: List.last(fixes) || state.fix, pose_at: t}}
  end

  # PubSub restarted: subscribe to the simulator's pose again
  def handle_info({:DOWN, _, :process, _, _} = msg, state), do: follow(state, msg)
  def handle_info({Follow, :retry, _} = msg, state), do: follow(state, msg)
  def handle_info(_other, state), do: {:noreply, state}

  defp follow(state, msg) do
    {_event, follow} = Follow.handle(state.follow, msg)
    {:noreply, %{state | follow: follow}}
  end

  defp invalid, do: %{x: 0.0, y: 0.0, z: 0.0, std: 0.0, valid: false, receivers: []}

  defp now, do: Neptunus.Clock.monotonic_ms() / 1000

  # --- HTTP -------------------------------------------------------------------------------------

  defp accept(listen, server) do
    case :gen_tcp.accept(listen) do
      {:ok, socket} ->
        pid = spawn(fn -> receive(do: (:go -> serve(socket, server))) end)
        :ok = :gen_tcp.controlling_process(socket, pid)
        send(pid, :go)
        accept(listen, server)

      {:error, :closed} ->
        :ok
    end
  end

  # one request after another on a kept-alive connection, until it closes
  defp serve(socket, server) do
    with {:ok, {:http_request, method, {:abs_path, path}, _version}} <-
           :gen_tcp.recv(socket, 0, 30_000),
         {:ok, headers} <- headers(socket, %{}),
         {:ok, body} <- body(socket, headers) do
      {status, answer} = answer(method, path, body, server)
      :ok = respond(socket, status, answer)
      if headers["connection"] == "close", do: :gen_tcp.close(socket), else: serve(socket, server)
    else
      _ -> :gen_tcp.close(socket)
    end
  catch
    :exit, _ -> :gen_tcp.close(socket)
  end

  defp headers(socket, acc) do
    case :gen_tcp.recv(socket, 0, 5_000) do
      {:ok, {:http_header, _, name, _, value}} ->
        headers(socket, Map.put(acc, name |> to_string() |> String.downcase(), value))

      {:ok, :http_eoh} ->
        {:ok, acc}

      other ->
        {:error, other}
    end
  end

  defp body(socket, headers) do
    case Integer.parse(Map.get(headers, "content-length", "0")) do
      {0, _} ->
        {:ok, ""}

      {n, _} when n > 0 and n <= @max_body ->
        :ok = :inet.setopts(socket, packet: :raw)
        result = :gen_tcp.recv(socket, n, 5_000)
        :ok = :inet.setopts(socket, packet: :http_bin)
        result

      _ ->
        {:error, :bad_length}
    end
  end

  defp answer(:GET, path, _body, server) do
    if path == UnderwaterGPS.acoustic_path(),
      do: {200, UnderwaterGPS.encode_fix(GenServer.call(server, :fix))},
      else: {404, UnderwaterGPS.encode_operation({:error, "not found"})}
  end

  defp answer(:PUT, path, body, server) do
    if path == UnderwaterGPS.depth_path() do
      case UnderwaterGPS.decode_depth(body) do
        {:ok, depth, temp} ->
          :ok = GenServer.call(server, {:depth, depth, temp})
          {200, UnderwaterGPS.encode_operation(:ok)}

        {:error, reason} ->
          {400, UnderwaterGPS.encode_operation({:error, reason})}
      end
    else
      {404, UnderwaterGPS.encode_operation({:error, "not found"})}
    end
  end

  defp answer(_method, _path, _body, _server),
    do: {405, UnderwaterGPS.encode_operation({:error, "method not allowed"})}

  defp respond(socket, status, body) do
    reason = %{200 => "OK", 400 => "Bad Request", 404 => "Not Found", 405 => "Method Not Allowed"}

    :gen_tcp.send(socket, [
      "HTTP/1.1 #{status} #{reason[status]}\r\n",
      "Content-Type: application/json\r\n",
      "Content-Length: #{byte_size(body)}\r\n\r\n",
      body
    ])
  end
end
