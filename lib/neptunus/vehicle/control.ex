defmodule Neptunus.Vehicle.Control do
  @moduledoc """
  A vehicle's control: takes the pilot's `thrust` and `stop` commands, runs the motion-mode
  thrust allocation (`Neptunus.Allocation`, thesis eq. 9.3) and commands the board.

  Safety: it drives the thrusters neutral when it starts (so a restart after any crash in
  the vehicle's tree leaves the thrusters neutral) and when the pilot's connection dies.

  Who is the pilot: until the helm (request/acknowledge handover) lands, the first client to
  send a command becomes the pilot; commands from anyone else are refused with
  `"not_in_control"` and change nothing. The pilot is released when its process exits.

  Events broadcast on `"vehicle:<id>"`: `pilot` `%{pilot: %{name: name} | nil}` and
  `stopped` `%{reason: reason}`.
  """
  use GenServer

  alias Neptunus.{Allocation, PubSub}
  alias Neptunus.Vehicle.{Board, Telemetry}

  @default_gain 0.5

  @typedoc "Who sends a command: the connection's process and the display name of its user."
  @type caller :: %{pid: pid(), name: String.t()}
  @type pilot :: %{pid: pid(), name: String.t(), monitor: reference()}
  @type reply :: {:ok, map()} | {:error, String.t()}

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            topic: String.t(),
            gain: float(),
            command: Neptunus.Allocation.motion(),
            thrusters: Neptunus.Allocation.thrusters(),
            pilot: Neptunus.Vehicle.Control.pilot() | nil
          }
    @enforce_keys [:id, :topic, :gain, :command, :thrusters]
    defstruct [:id, :topic, :gain, :command, :thrusters, :pilot]
  end

  @doc "Options: `:id` (required), `:gain` (k in [0, 1], default #{@default_gain})."
  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts) do
    GenServer.start_link(__MODULE__, opts, name: via(Keyword.fetch!(opts, :id)))
  end

  @doc """
  Thrust command from `caller`: `params` is the untrusted JSON object
  `%{"mode" => "motion", "surge" => s, "heave" => h, "yaw" => y}`, values in [-1, 1].

  Replies `{:ok, %{command: ..., thrusters: ...}}` or `{:error, reason}` (nothing changed).
  """
  @spec thrust(String.t(), caller(), map()) :: reply()
  def thrust(id, caller, params), do: GenServer.call(via(id), {:thrust, caller, params})

  @doc "Stops the thrusters (neutral). `reason` is shown to everyone watching."
  @spec stop(String.t(), caller(), String.t()) :: reply()
  def stop(id, caller, reason), do: GenServer.call(via(id), {:stop, caller, reason})

  @doc """
  Releases control if `caller` is the pilot: thrusters go neutral and `stopped` is broadcast
  with `reason` (e.g. `pilot_left`, `pilot_disconnected`). A no-op for anyone else.
  """
  @spec release(String.t(), caller(), String.t()) :: :ok
  def release(id, caller, reason), do: GenServer.call(via(id), {:release, caller, reason})

  @doc "Current control status: command, thrusters, gain and pilot (`%{name}` or nil)."
  @spec status(String.t()) :: map()
  def status(id), do: GenServer.call(via(id), :status)

  defp via(id), do: Neptunus.Fleet.via(__MODULE__, id)

  # Callbacks

  @impl true
  def init(opts) do
    id = Keyword.fetch!(opts, :id)

    state = %State{
      id: id,
      topic: Telemetry.topic(id),
      gain: Keyword.get(opts, :gain, @default_gain),
      command: zero_command(),
      thrusters: Allocation.neutral()
    }

    {:ok, state, {:continue, :neutral}}
  end

  @impl true
  def handle_continue(:neutral, state), do: {:noreply, apply_command(state, zero_command())}

  @impl true
  def handle_call({:thrust, caller, params}, _from, state) do
    with {:ok, state} <- authorize(state, caller),
         :ok <- motion_mode(params),
         {:ok, command} <- Allocation.validate_motion(params) do
      state = apply_command(state, command)
      {:reply, {:ok, output(state)}, state}
    else
      {:error, reason} -> {:reply, {:error, reason}, state}
    end
  end

  def handle_call({:stop, caller, reason}, _from, state) do
    case authorize(state, caller) do
      {:ok, state} ->
        state = safety_stop(state, reason)
        {:reply, {:ok, output(state)}, state}

      {:error, reason} ->
        {:reply, {:error, reason}, state}
    end
  end

  def handle_call({:release, %{pid: pid}, reason}, _from, %State{pilot: %{pid: pid}} = state) do
    Process.demonitor(state.pilot.monitor, [:flush])
    state = safety_stop(%{state | pilot: nil}, reason)
    broadcast_pilot(state)
    {:reply, :ok, state}
  end

  def handle_call({:release, _caller, _reason}, _from, state), do: {:reply, :ok, state}

  def handle_call(:status, _from, state) do
    {:reply, Map.merge(output(state), %{gain: state.gain, pilot: public_pilot(state.pilot)}),
     state}
  end

  @impl true
  def handle_info({:DOWN, ref, :process, _pid, _reason}, %State{pilot: %{monitor: ref}} = state) do
    state = safety_stop(%{state | pilot: nil}, "pilot_disconnected")
    broadcast_pilot(state)
    {:noreply, state}
  end

  def handle_info({:DOWN, _ref, :process, _pid, _reason}, state), do: {:noreply, state}

  # The first caller becomes the pilot; afterwards only the pilot may command.
  defp authorize(%State{pilot: nil} = state, %{pid: pid, name: name}) do
    state = %{state | pilot: %{pid: pid, name: name, monitor: Process.monitor(pid)}}
    broadcast_pilot(state)
    {:ok, state}
  end

  defp authorize(%State{pilot: %{pid: pid}} = state, %{pid: pid}), do: {:ok, state}
  defp authorize(_state, _caller), do: {:error, "not_in_control"}

  defp motion_mode(%{"mode" => "motion"}), do: :ok

  defp motion_mode(%{"mode" => mode}) when is_binary(mode),
    do: {:error, "control mode #{inspect(mode)} is not available: use \"motion\""}

  defp motion_mode(_), do: {:error, "mode must be \"motion\""}

  defp safety_stop(state, reason) do
    state = apply_command(state, zero_command())
    PubSub.broadcast(state.topic, "stopped", %{reason: reason})
    state
  end

  defp apply_command(state, command) do
    thrusters = Allocation.motion(command, state.gain)
    Board.go(state.id, thrusters)
    Telemetry.control(state.id, command, thrusters)
    %{state | command: command, thrusters: thrusters}
  end

  defp broadcast_pilot(state) do
    PubSub.broadcast(state.topic, "pilot", %{pilot: public_pilot(state.pilot)})
  end

  defp output(state),
    do: %{command: state.command, thrusters: Allocation.with_us(state.thrusters)}

  defp public_pilot(nil), do: nil
  defp public_pilot(%{name: name}), do: %{name: name}

  defp zero_command, do: %{surge: 0.0, heave: 0.0, yaw: 0.0}
end
