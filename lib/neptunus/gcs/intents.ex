defmodule Neptunus.GCS.Intents do
  @moduledoc """
  How a ground station session's intents (`t:Neptunus.GCS.Session.intent/0`) are carried
  out: through the same public entry points a browser's commands take — the vehicle's
  `Neptunus.Vehicle.Helm` (who may; the deadman; every command runs in the helm's process),
  `Neptunus.Vehicle.Control` and, for an ArduSub vehicle, its board — never around the helm.
  Called by `Neptunus.GCS.Link` (thrust and heartbeats in its own process, the rest in a
  task of its own, so a slow one never holds the pilot's input up).
  """

  alias Neptunus.GCS.Manual
  alias Neptunus.Vehicle.{Board, Control, Helm}

  # how long an arm or a mode change waits for an ArduSub vehicle's answer (its board gives
  # up after 3 s)
  @vehicle_answer_ms 4_000

  @typedoc "The vehicle an intent is for: `%{id, board, wiring}`."
  @type vehicle :: %{
          required(:id) => String.t(),
          required(:board) => atom(),
          optional(atom()) => term()
        }

  @doc "Carries `intent` out for `party` on `vehicle`: `{:ok, map}` or `{:error, reason}`."
  @spec run(Neptunus.GCS.Session.intent(), vehicle(), Helm.party()) :: term()
  def run({:thrust, axes, epoch}, %{id: id}, party) do
    # sway only to a vehicle that can sway (its board's axes, as the vehicle registered them)
    vehicle_axes =
      case Board.capabilities(id) do
        %{axes: vehicle_axes} -> vehicle_axes
        nil -> []
      end

    Helm.thrust(id, party, Manual.thrust_payload(axes, vehicle_axes, epoch))
  end

  def run(:heartbeat, %{id: id}, party), do: Helm.heartbeat(id, party)
  def run(:status, %{id: id}, _party), do: {:ok, Helm.status(id)}
  def run(:request_control, %{id: id}, party), do: Helm.request_control(id, party)
  def run(:take_control, %{id: id}, party), do: Helm.take_control(id, party)
  def run(:release_control, %{id: id}, party), do: Helm.release_control(id, party)
  def run({:answer, accept}, %{id: id}, party), do: Helm.answer_request(id, party, accept)

  def run({:commands, commands}, vehicle, party) do
    Enum.reduce_while(commands, {:ok, %{}}, fn command, _ ->
      case command(command, vehicle, party) do
        {:ok, reply} -> {:cont, {:ok, reply}}
        {:error, _} = error -> {:halt, error}
      end
    end)
  end

  def run({:arm, arm?}, %{id: id}, party),
    do: board_request(id, party, &Board.arm(&1, arm?, &2))

  def run({:param_set, _name, set}, vehicle, party) do
    applied =
      case set do
        {:control, event, payload} -> command({event, payload}, vehicle, party)
        {:tune, payload} -> Control.tune(vehicle.id, payload)
      end

    case applied do
      {:ok, _} -> {:ok, param_sources(vehicle)}
      {:error, reason} -> {:error, reason, param_sources(vehicle)}
    end
  end

  def run(:params, vehicle, _party), do: {:ok, param_sources(vehicle)}

  # a control command from the pilot, as the operator page sends it; on a vehicle whose
  # autopilots are its own (its board's capabilities, e.g. ArduSub's flight modes) the
  # `autopilot` command is the board's (Board.command/3), which answers
  defp command({"autopilot", payload} = command, %{id: id} = vehicle, party) do
    case Board.capabilities(id) do
      %{autopilots: :vehicle} -> board_request(id, party, &vehicle_autopilot(&1, payload, &2))
      _ -> control_command(command, vehicle, party)
    end
  end

  defp command(command, vehicle, party), do: control_command(command, vehicle, party)

  defp control_command({event, payload}, %{id: id}, party),
    do: Helm.command(id, party, :none, fn -> Control.command(id, event, payload) end)

  # the validated autopilot command for the vehicle itself; a bad payload refused at once
  defp vehicle_autopilot(id, payload, notify) do
    with {:ok, {:autopilot, _} = command} <-
           Neptunus.Control.Command.validate("autopilot", payload),
         do: Board.command(id, command, notify)
  end

  # a request to the board, after the helm's pilot check, answered when the vehicle answers
  defp board_request(id, party, request) do
    me = self()
    ref = make_ref()
    notify = fn result -> send(me, {ref, result}) end

    with {:ok, _} <- Helm.board_request(id, party, request, notify) do
      receive do
        {^ref, :ok} -> {:ok, %{}}
        {^ref, {:error, reason}} -> {:error, reason}
      after
        @vehicle_answer_ms -> {:error, "no answer from the vehicle"}
      end
    end
  end

  @doc "What a vehicle's parameters are read from (`Neptunus.GCS.Params.sources/0`)."
  @spec param_sources(vehicle()) :: Neptunus.GCS.Params.sources()
  def param_sources(%{id: id} = vehicle) do
    %{
      control: Control.status(id),
      gains: Control.tuning(id).gains,
      limits: Control.limits(id),
      helm: Helm.status(id),
      wiring: Map.get(vehicle, :wiring)
    }
  end
end
