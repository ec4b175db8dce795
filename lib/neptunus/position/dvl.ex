defmodule Neptunus.Position.DVL do
  @moduledoc """
  The driver of a Water Linked DVL (A50, A125): a TCP client of its JSON protocol
  (`Neptunus.Protocol.WaterLinkedDVL`, port 16171) reporting to the vehicle's navigation
  (`Neptunus.Position.Source`).

    * It connects (`host`, `port`), and reconnects after a failure or a close with backoff
      (0.5 s doubling to 5 s); navigation hears `{:link, :up}` and `{:link, {:down, reason}}`
      (`"connection refused"`, `"closed by the DVL"`, …).
    * Each line (`\\n`-framed, at most #{8192} bytes: longer ones are dropped as garbage) is
      decoded; a velocity report becomes a reading at the time it was measured (its age from
      its own stamps, `Neptunus.Position.Reading.dvl/2`), a dead-reckoning report goes along
      for display; a line that cannot be read goes to navigation as `{:garbage, reason}`
      (navigation counts it, and says why while nothing usable comes).
    * `command/3` sends `reset_dead_reckoning`, `calibrate_gyro` (the DVL should be still;
      it may take up to 15 s) or `get_config` and waits for the DVL's response (20 s at most):
      `{:ok, result}` or `{:error, reason}` — the DVL's `error_message`, `"DVL not
      connected"`, `"no response from the DVL in 20 s"`. One command of a kind at a time.

  Options: `:id`, `:name` (default `:dvl`), `:host`, `:port` (or `:endpoint`, a function
  returning `{host, port}` when connecting: the simulated DVL's port is known only once it
  listens), `:connect_timeout_ms` (default 2000).
  """
  use GenServer

  require Logger

  alias Neptunus.Position.{Reading, Source}
  alias Neptunus.Protocol.{Lines, WaterLinkedDVL}
  alias Neptunus.Vehicle.Board.Backoff

  @behaviour Source

  @max_line 8192
  @command_timeout_ms 20_000

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            name: atom(),
            endpoint: (() -> {String.t() | :inet.ip_address(), :inet.port_number()}),
            connect_timeout_ms: pos_integer(),
            socket: :gen_tcp.socket() | nil,
            lines: Neptunus.Protocol.Lines.t(),
            backoff: Neptunus.Vehicle.Board.Backoff.t(),
            up_since_ms: integer() | nil,
            pending: %{String.t() => {GenServer.from(), reference()}},
            down_reason: String.t() | nil
          }
    @enforce_keys [:id, :name, :endpoint, :connect_timeout_ms, :lines, :backoff]
    defstruct [
      :id,
      :name,
      :endpoint,
      :connect_timeout_ms,
      :socket,
      :lines,
      :backoff,
      :up_since_ms,
      :down_reason,
      pending: %{}
    ]
  end

  @impl Source
  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts), do: Source.start_server(__MODULE__, opts, :dvl)

  @impl Source
  @spec command(String.t(), atom(), atom()) :: {:ok, term()} | {:error, String.t()}
  def command(id, name, command) do
    if command in WaterLinkedDVL.commands(),
      do: GenServer.call(Source.via(id, name), {:command, command}, @command_timeout_ms + 1_000),
      else: {:error, "unknown DVL command #{inspect(command)}"}
  end

  @doc "Whether the driver is connected (for tests and diagnostics)."
  @spec connected?(String.t(), atom()) :: boolean()
  def connected?(id, name \\ :dvl), do: GenServer.call(Source.via(id, name), :connected?)

  # Callbacks

  @impl true
  def init(opts) do
    endpoint =
      Source.endpoint(opts, fn ->
        {Keyword.fetch!(opts, :host), Keyword.get(opts, :port, WaterLinkedDVL.port())}
      end)

    state = %State{
      id: Keyword.fetch!(opts, :id),
      name: Keyword.fetch!(opts, :name),
      endpoint: endpoint,
      connect_timeout_ms: Keyword.get(opts, :connect_timeout_ms, 2_000),
      lines: Lines.new(@max_line),
      backoff: Backoff.new(500, 5_000)
    }

    {:ok, state, {:continue, :connect}}
  end

  @impl true
  def handle_continue(:connect, state), do: {:noreply, connect(state)}

  @impl true
  def handle_call(:connected?, _from, state), do: {:reply, state.socket != nil, state}

  def handle_call({:command, _command}, _from, %State{socket: nil} = state),
    do: {:reply, {:error, "DVL not connected" <> down(state)}, state}

  def handle_call({:command, command}, from, state) do
    key = Atom.to_string(command)

    if Map.has_key?(state.pending, key) do
      {:reply, {:error, "a #{key} is already waiting for the DVL's response"}, state}
    else
      case :gen_tcp.send(state.socket, WaterLinkedDVL.encode_command(command)) do
        :ok ->
          timer = Process.send_after(self(), {:command_timeout, key}, @command_timeout_ms)
          {:noreply, %{state | pending: Map.put(state.pending, key, {from, timer})}}

        {:error, reason} ->
          {:reply, {:error, "DVL not connected: #{Source.describe_error(reason)}"}, state}
      end
    end
  end

  @impl true
  def handle_info({:tcp, socket, data}, %State{socket: socket} = state) do
    :ok = :inet.setopts(socket, active: :once)
    overlong = state.lines.overlong
    {lines, framer} = Lines.feed(state.lines, data)
    now = Source.now()

    if framer.overlong > overlong,
      do:
        Source.report(
          state.id,
          state.name,
          {:garbage, "a line longer than #{@max_line} bytes"},
          now
        )

    {:noreply, Enum.reduce(lines, %{state | lines: framer}, &line(&2, &1, now))}
  end

  def handle_info({:tcp_closed, socket}, %State{socket: socket} = state),
    do: {:noreply, lost(state, "closed by the DVL")}

  def handle_info({:tcp_error, socket, reason}, %State{socket: socket} = state),
    do: {:noreply, lost(state, Source.describe_error(reason))}

  def handle_info(:reconnect, state), do: {:noreply, connect(state)}

  def handle_info({:command_timeout, key}, state) do
    case Map.pop(state.pending, key) do
      {{from, _timer}, pending} ->
        GenServer.reply(
          from,
          {:error, "no response from the DVL in #{div(@command_timeout_ms, 1000)} s"}
        )

        {:noreply, %{state | pending: pending}}

      {nil, _} ->
        {:noreply, state}
    end
  end

  def handle_info(_stale, state), do: {:noreply, state}

  # --- the link ---

  defp connect(state) do
    {host, port} = state.endpoint.()
    host = if is_binary(host), do: String.to_charlist(host), else: host
    opts = [:binary, active: :once, packet: :raw, nodelay: true, keepalive: true]

    case :gen_tcp.connect(host, port, opts, state.connect_timeout_ms) do
      {:ok, socket} ->
        Source.report(state.id, state.name, {:link, :up}, Source.now())
        Logger.info("vehicle #{state.id}: DVL #{state.name} connected to #{show(host)}:#{port}")

        %{
          state
          | socket: socket,
            lines: Lines.new(@max_line),
            up_since_ms: Neptunus.Clock.monotonic_ms(),
            down_reason: nil
        }

      {:error, reason} ->
        retry(state, Source.describe_error(reason))
    end
  end

  defp lost(state, reason) do
    _ = :gen_tcp.close(state.socket)
    up_ms = Neptunus.Clock.monotonic_ms() - (state.up_since_ms || Neptunus.Clock.monotonic_ms())

    for {_key, {from, timer}} <- state.pending do
      Process.cancel_timer(timer)
      GenServer.reply(from, {:error, "DVL disconnected: #{reason}"})
    end

    Logger.warning("vehicle #{state.id}: DVL #{state.name} disconnected: #{reason}")

    retry(
      %{state | socket: nil, pending: %{}, backoff: Backoff.up_for(state.backoff, up_ms)},
      reason
    )
  end

  defp retry(state, reason) do
    if state.down_reason != reason,
      do: Source.report(state.id, state.name, {:link, {:down, reason}}, Source.now())

    {delay, backoff} = Backoff.next(state.backoff)
    Process.send_after(self(), :reconnect, delay)
    %{state | backoff: backoff, down_reason: reason}
  end

  defp show(host) when is_tuple(host), do: host |> :inet.ntoa() |> List.to_string()
  defp show(host), do: List.to_string(host)

  defp down(%State{down_reason: nil}), do: ""
  defp down(%State{down_reason: reason}), do: " (#{reason})"

  # --- lines ---

  defp line(state, "", _now), do: state

  defp line(state, line, now) do
    case WaterLinkedDVL.decode(line) do
      {:ok, {:response, response}} ->
        respond(state, response)

      {:ok, report} ->
        case Reading.dvl(report, now) do
          nil -> state
          reading -> tap(state, fn _ -> Source.report(state.id, state.name, reading, now) end)
        end

      {:error, reason} ->
        Source.report(state.id, state.name, {:garbage, reason}, now)
        state
    end
  end

  defp respond(state, %{to: to} = response) do
    case Map.pop(state.pending, to) do
      {{from, timer}, pending} ->
        Process.cancel_timer(timer)

        reply =
          if response.success,
            do: {:ok, response.result},
            else: {:error, "the DVL refused #{to}: #{response.error_message}"}

        GenServer.reply(from, reply)
        %{state | pending: pending}

      {nil, _} ->
        state
    end
  end
end
