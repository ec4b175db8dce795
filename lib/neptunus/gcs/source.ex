defmodule Neptunus.GCS.Source do
  @moduledoc """
  One vehicle as a MAVLink system, for every ground station session of the node: it follows
  the vehicle's broadcasts (`telemetry`, `helm`, `stopped` on `"vehicle:<id>"`, `log` on
  `"log:<id>"`) and, 20 times a second while any session listens, builds its messages
  (`Neptunus.GCS.Vehicle`) and **encodes each once**; every session (`Neptunus.GCS.Link`)
  gets the same frames and only stamps its own sequence number (and signature) on those its
  schedule says are due.

  Sessions listen by registering in `Neptunus.GCS.Registry` under `{:vehicle, sysid}` and get:

    * `{:gcs_tick, sysid, now_ms, view, frames}` — every tick: the vehicle's `view`
      (`%{helm, control, board, messages}`, what a session decides with; `messages` the
      streamed ones it has now) and its frames by message name
      (a binary, or a list of binaries for NAMED_VALUE_FLOAT), AUTOPILOT_VERSION among them
      (sent on request only);
    * `{:gcs_event, sysid, frames}` — at once: CONTROL_STATUS when the helm changes, and
      STATUSTEXT for the vehicle's stops, its helm's changes and its log entries (at most
      #{10} a second; more are dropped and counted).

  Frames are encoded from the vehicle's system id and component 1 with sequence number 0.
  """
  use GenServer

  require Logger

  alias Neptunus.Periodic
  alias Neptunus.PubSub.Follow
  alias Neptunus.GCS.Vehicle
  alias Neptunus.Protocol.MAVLink
  alias Neptunus.Vehicle.{Helm, Telemetry}

  @hz 20
  @texts_per_s 10

  # MAV_SEVERITY
  @warning 4
  @notice 5
  @info 6

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            vehicle: Neptunus.GCS.Vehicle.t(),
            follow: Neptunus.PubSub.Follow.t(),
            periodic: Neptunus.Periodic.t(),
            autopilot_version: binary(),
            pilot: term(),
            texts: {integer(), non_neg_integer()},
            text_id: pos_integer(),
            dropped_texts: non_neg_integer()
          }
    @enforce_keys [:vehicle, :follow, :periodic, :autopilot_version]
    defstruct @enforce_keys ++ [pilot: nil, texts: {0, 0}, text_id: 1, dropped_texts: 0]
  end

  @doc """
  Options: `:id` (the vehicle), `:sysid` (its MAVLink system id), `:board` (its board type),
  `:hz` (default #{@hz}).
  """
  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts) do
    GenServer.start_link(__MODULE__, opts, name: via(Keyword.fetch!(opts, :sysid)))
  end

  @spec child_spec(keyword()) :: Supervisor.child_spec()
  def child_spec(opts),
    do: %{
      id: {__MODULE__, Keyword.fetch!(opts, :sysid)},
      start: {__MODULE__, :start_link, [opts]}
    }

  @doc "The registry key under which sessions listen to vehicle `sysid`."
  @spec key(1..255) :: {:vehicle, 1..255}
  def key(sysid), do: {:vehicle, sysid}

  @doc "STATUSTEXTs dropped over the rate limit (for tests and diagnostics)."
  @spec dropped_texts(1..255) :: non_neg_integer()
  def dropped_texts(sysid), do: GenServer.call(via(sysid), :dropped_texts)

  defp via(sysid), do: {:via, Registry, {Neptunus.GCS.Names, {__MODULE__, sysid}}}

  # Callbacks

  @impl true
  def init(opts) do
    id = Keyword.fetch!(opts, :id)
    sysid = Keyword.fetch!(opts, :sysid)
    board = Keyword.get(opts, :board, :simulated)
    vehicle = Vehicle.new(id, sysid, board, Neptunus.Clock.monotonic_ms())

    {:ok, version} =
      encode(vehicle, :autopilot_version, Vehicle.autopilot_version(sysid, node_version()))

    state = %State{
      vehicle: vehicle,
      follow: Follow.new([Telemetry.topic(id), Telemetry.log_topic(id)]),
      periodic: Periodic.new(Keyword.get(opts, :hz, @hz)),
      autopilot_version: version
    }

    {:ok, state, {:continue, :subscribe}}
  end

  @impl true
  def handle_continue(:subscribe, state) do
    state = follow(state, Follow.subscribe(state.follow))
    Periodic.arm(state.periodic, :tick)
    {:noreply, state}
  end

  @impl true
  def handle_call(:dropped_texts, _from, state), do: {:reply, state.dropped_texts, state}

  @impl true
  def handle_info(:tick, state) do
    {_due, periodic} = Periodic.advance(state.periodic, Neptunus.Clock.monotonic_native())
    Periodic.arm(periodic, :tick)
    state = %{state | periodic: periodic}
    sysid = state.vehicle.sysid

    # nothing is built while no session listens
    case Registry.lookup(Neptunus.GCS.Registry, key(sysid)) do
      [] ->
        :ok

      listeners ->
        now = Neptunus.Clock.monotonic_ms()
        frames = frames(state, now)
        message = {:gcs_tick, sysid, now, view(state.vehicle, frames), frames}
        for {pid, _} <- listeners, do: send(pid, message)
    end

    {:noreply, state}
  end

  def handle_info({:pubsub, _topic, "telemetry", payload}, state),
    do: {:noreply, put_in(state.vehicle.telemetry, payload)}

  def handle_info({:pubsub, _topic, "helm", helm}, state) do
    state = put_in(state.vehicle.helm, helm)
    {:ok, status} = encode(state.vehicle, :control_status, Vehicle.control_status(state.vehicle))
    pilot = helm[:pilot] && helm.pilot[:id]

    texts =
      cond do
        pilot == state.pilot ->
          []

        pilot == nil ->
          [{@notice, "helm free"}]

        true ->
          [{@notice, "helm: #{helm.pilot[:name]} pilots"}]
      end

    texts =
      case helm do
        %{request: %{from: %{name: name}}} -> texts ++ [{@info, "#{name} asks for the helm"}]
        %{takeover: %{by: %{name: name}}} -> texts ++ [{@warning, "#{name} takes over"}]
        _ -> texts
      end

    state = %{state | pilot: pilot}
    {state, text_frames} = texts(state, texts)
    event(state, [status | text_frames])
    {:noreply, state}
  end

  def handle_info({:pubsub, _topic, "stopped", %{reason: reason}}, state) do
    {state, frames} = texts(state, [{@warning, "stopped: #{reason}"}])
    event(state, frames)
    {:noreply, state}
  end

  # the vehicle's log entries (stops are already said)
  def handle_info({:pubsub, _topic, "log", %{category: category} = entry}, state)
      when category != "safety" do
    severity =
      case entry[:level] do
        "error" -> 3
        "warning" -> @warning
        _ -> @info
      end

    {state, frames} = texts(state, [{severity, "#{category}: #{entry[:message]}"}])
    event(state, frames)
    {:noreply, state}
  end

  def handle_info({:pubsub, _topic, _event, _payload}, state), do: {:noreply, state}

  # the PubSub scope restarted: subscribe again (what was missed is the next tick's)
  def handle_info({:DOWN, _ref, :process, _pid, _reason} = msg, state),
    do: {:noreply, follow(state, Follow.handle(state.follow, msg))}

  def handle_info({Follow, :retry, _} = msg, state),
    do: {:noreply, follow(state, Follow.handle(state.follow, msg))}

  def handle_info(msg, state) do
    Logger.debug("gcs source #{state.vehicle.id} ignored #{inspect(msg)}")
    {:noreply, state}
  end

  # --- frames -------------------------------------------------------------------------------

  defp frames(state, now) do
    state.vehicle
    |> Vehicle.streamed(now, Neptunus.Clock.wall_us())
    |> Map.new(fn
      {name, list} when is_list(list) ->
        {name, for(f <- list, do: encode!(state.vehicle, name, f))}

      {name, fields} ->
        {name, encode!(state.vehicle, name, fields)}
    end)
    |> Map.put(:autopilot_version, state.autopilot_version)
  end

  defp view(vehicle, frames) do
    %{
      helm: vehicle.helm,
      control: vehicle.telemetry && vehicle.telemetry[:control],
      board: vehicle.board,
      messages: frames |> Map.keys() |> List.delete(:autopilot_version)
    }
  end

  defp encode(vehicle, name, fields),
    do:
      MAVLink.encode(name, fields, %{
        system: vehicle.sysid,
        component: Vehicle.component(),
        seq: 0
      })

  defp encode!(vehicle, name, fields) do
    case encode(vehicle, name, fields) do
      {:ok, frame} -> frame
      {:error, reason} -> raise ArgumentError, "#{name} #{inspect(fields)}: #{inspect(reason)}"
    end
  end

  # STATUSTEXT frames of `texts` ({severity, text}), at most @texts_per_s a second
  defp texts(state, texts) do
    now_s = div(Neptunus.Clock.monotonic_ms(), 1000)

    Enum.reduce(texts, {state, []}, fn {severity, text}, {state, frames} ->
      {second, sent} = state.texts
      sent = if second == now_s, do: sent, else: 0

      if sent >= @texts_per_s do
        {%{state | dropped_texts: state.dropped_texts + 1, texts: {now_s, sent}}, frames}
      else
        id = state.text_id
        text = "#{state.vehicle.id}: #{text}"

        new =
          for fields <- Vehicle.statustext(severity, text, id),
              do: encode!(state.vehicle, :statustext, fields)

        {%{state | texts: {now_s, sent + 1}, text_id: rem(id, 0xFFFF) + 1}, frames ++ new}
      end
    end)
  end

  defp event(_state, []), do: :ok

  defp event(state, frames) do
    sysid = state.vehicle.sysid

    Registry.dispatch(Neptunus.GCS.Registry, key(sysid), fn listeners ->
      for {pid, _} <- listeners, do: send(pid, {:gcs_event, sysid, frames})
    end)
  end

  # Subscribed (again): what was broadcast before, the helm as it stands and the latest
  # telemetry. Otherwise the follow tries again.
  defp follow(state, {:subscribed, follow}) do
    id = state.vehicle.id
    vehicle = %{state.vehicle | helm: helm_status(id), telemetry: latest(id)}

    %{
      state
      | follow: follow,
        vehicle: vehicle,
        pilot: vehicle.helm && vehicle.helm[:pilot] && vehicle.helm.pilot[:id]
    }
  end

  defp follow(state, {_waiting_lost_or_other, follow}), do: %{state | follow: follow}

  defp helm_status(id) do
    Helm.status(id)
  catch
    :exit, _ -> nil
  end

  defp latest(id) do
    Telemetry.latest(id)
  catch
    :exit, _ -> nil
  end

  defp node_version, do: :neptunus |> Application.spec(:vsn) |> to_string()
end
