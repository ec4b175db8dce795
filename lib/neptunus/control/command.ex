defmodule Neptunus.Control.Command do
  @moduledoc """
  Validation of the pilot's control commands (untrusted JSON objects with string keys, as
  decoded from the wire) into the terms `Neptunus.Control.Core` takes. Pure; every error is a
  sentence naming the field, and a refused command changes nothing.

  | Event | Payload | Command |
  |---|---|---|
  | `set_control_mode` | `{mode: "motion" \\| "manual" \\| "dp"}` | `{:set_control_mode, mode}` |
  | `thrust` | `{mode: "motion", surge, heave, yaw, sway?}` or `{mode: "manual", port, vertical, starboard}`, each in [-1, 1] (`sway` to starboard, on a vehicle that has it) | `{:thrust, :motion, %{surge, heave, yaw}}` (with `sway` when given) / `{:thrust, :manual, %{port, vertical, starboard}}` |
  | `set_gain` | `{value}` in [0, 1] | `{:set_gain, k}` |
  | `set_lights`, `set_laser` | `{value}` integer 0..255 | `{:set_lights, n}`, `{:set_laser, n}` |
  | `set_tilt` | `{value}` rad in [−π/4, π/4] | `{:set_tilt, rad}` |
  | `autopilot` | `{depth?, heading?}`: a number (depth in [0, #{200}] m; heading in [−2π, 2π] rad, wrapped to [0, 2π)), `"hold"` or `null` | `{:autopilot, %{depth: v, heading: v}}`, absent keys `:unchanged` |
  | `set_run_mode` | `{mode: "normal" \\| "simulator"}` | `{:set_run_mode, mode}` |
  | `mission` | `{action: "start" \\| "plan", waypoints: [...]}` or `{action, survey: {...}}` (`Neptunus.Control.Mission.parse/1`); `{action: "pause" \\| "resume" \\| "abort"}` | `{:mission, {:start \\| :plan, waypoints}}`, `{:mission, :pause \\| :resume \\| :abort}` |

  The thrust payload's `epoch` stamp is the helm's business and is removed before it gets
  here (`Neptunus.Vehicle.Helm.thrust/3`).

      iex> Neptunus.Control.Command.validate("set_lights", %{"value" => 128})
      {:ok, {:set_lights, 128}}

      iex> Neptunus.Control.Command.validate("set_gain", %{"value" => 1.5})
      {:error, "value must be a number in [0, 1], got 1.5"}

      iex> Neptunus.Control.Command.validate("autopilot", %{"depth" => "hold", "heading" => nil})
      {:ok, {:autopilot, %{depth: :hold, heading: nil}}}
  """

  alias Neptunus.PID
  alias Neptunus.Validate, as: V

  @max_depth 200
  @tilt_max :math.pi() / 4
  @two_pi 2 * :math.pi()

  @events ~w(set_control_mode thrust set_gain set_lights set_laser set_tilt autopilot set_run_mode
             mission)
  @control_modes %{"motion" => :motion, "manual" => :manual, "dp" => :dp}
  @run_modes %{"normal" => :normal, "simulator" => :simulator}

  @type control_mode :: :motion | :manual | :dp
  @type run_mode :: :normal | :simulator
  @type setpoint :: :unchanged | :hold | nil | float()
  @type t ::
          {:set_control_mode, control_mode()}
          | {:thrust, :motion,
             %{
               required(:surge) => float(),
               required(:heave) => float(),
               required(:yaw) => float(),
               optional(:sway) => float()
             }}
          | {:thrust, :manual, %{port: float(), vertical: float(), starboard: float()}}
          | {:set_gain, float()}
          | {:set_lights, 0..255}
          | {:set_laser, 0..255}
          | {:set_tilt, float()}
          | {:autopilot, %{depth: setpoint(), heading: setpoint()}}
          | {:set_run_mode, run_mode()}
          | {:mission, {:start | :plan, [Neptunus.Control.Mission.waypoint()]}}
          | {:mission, :pause | :resume | :abort}

  @doc "The events validated here."
  @spec events() :: [String.t()]
  def events, do: @events

  @doc "The largest camera tilt either way (rad, π/4)."
  @spec tilt_max() :: float()
  def tilt_max, do: @tilt_max

  @doc "Validates the payload of `event`."
  @spec validate(String.t(), term()) :: {:ok, t()} | {:error, String.t()}
  def validate(event, payload) when event in @events and not is_map(payload),
    do: {:error, "#{event} payload must be an object, got #{V.show(payload)}"}

  def validate("set_control_mode", payload) do
    with {:ok, mode} <- mode(payload, @control_modes), do: {:ok, {:set_control_mode, mode}}
  end

  def validate("mission", %{"action" => action} = payload) when action in ["start", "plan"] do
    with {:ok, waypoints} <- Neptunus.Control.Mission.parse(Map.delete(payload, "action")),
         do: {:ok, {:mission, {mission_action(action), waypoints}}}
  end

  def validate("mission", %{"action" => action} = payload)
      when action in ["pause", "resume", "abort"] do
    with :ok <- V.object(payload, "", ["action"]),
         do: {:ok, {:mission, mission_action(action)}}
  end

  def validate("mission", %{"action" => action}),
    do:
      {:error,
       "action must be \"start\", \"plan\", \"pause\", \"resume\" or \"abort\", got #{V.show(action)}"}

  def validate("mission", _payload), do: {:error, "missing field: action"}

  def validate("set_run_mode", payload) do
    with {:ok, mode} <- mode(payload, @run_modes), do: {:ok, {:set_run_mode, mode}}
  end

  def validate("thrust", %{"mode" => "motion"} = payload),
    do: axes(payload, :motion, ~w(surge heave yaw), ~w(sway))

  def validate("thrust", %{"mode" => "manual"} = payload),
    do: axes(payload, :manual, ~w(port vertical starboard), [])

  def validate("thrust", %{"mode" => mode}),
    do: {:error, "mode must be \"motion\" or \"manual\", got #{V.show(mode)}"}

  def validate("thrust", _payload), do: {:error, "missing field: mode"}

  def validate("set_gain", payload) do
    with {:ok, k} <- value(payload, &V.number(&1, &2, min: 0, max: 1)), do: {:ok, {:set_gain, k}}
  end

  def validate(event, payload) when event in ["set_lights", "set_laser"] do
    with {:ok, n} <- value(payload, &byte/2), do: {:ok, {String.to_existing_atom(event), n}}
  end

  def validate("set_tilt", payload) do
    with {:ok, rad} <- value(payload, &tilt/2), do: {:ok, {:set_tilt, rad}}
  end

  def validate("autopilot", payload) do
    with :ok <- V.object(payload, "", [], ["depth", "heading"]),
         :ok <- some_axis(payload),
         {:ok, depth} <- setpoint(payload, "depth", &depth/2),
         {:ok, heading} <- setpoint(payload, "heading", &heading/2) do
      {:ok, {:autopilot, %{depth: depth, heading: heading}}}
    end
  end

  def validate(event, _payload), do: {:error, "unknown control command: #{event}"}

  defp mode(payload, modes) do
    with :ok <- V.object(payload, "", ["mode"]) do
      case Map.fetch(modes, payload["mode"]) do
        {:ok, mode} ->
          {:ok, mode}

        :error ->
          names = modes |> Map.keys() |> Enum.sort() |> Enum.map_join(", ", &inspect/1)
          {:error, "mode must be one of #{names}, got #{V.show(payload["mode"])}"}
      end
    end
  end

  defp axes(payload, mode, keys, optional) do
    given = Enum.filter(optional, &Map.has_key?(payload, &1))

    with :ok <- V.object(payload, "", ["mode" | keys], optional) do
      Enum.reduce_while(keys ++ given, {:ok, %{}}, fn key, {:ok, acc} ->
        case V.required(payload, "", key, &V.number(&1, &2, min: -1, max: 1)) do
          {:ok, x} -> {:cont, {:ok, Map.put(acc, String.to_atom(key), x)}}
          error -> {:halt, error}
        end
      end)
      |> case do
        {:ok, values} -> {:ok, {:thrust, mode, values}}
        error -> error
      end
    end
  end

  defp value(payload, check) do
    with :ok <- V.object(payload, "", ["value"]), do: V.required(payload, "", "value", check)
  end

  defp byte(value, _path) when is_integer(value) and value in 0..255, do: {:ok, value}

  defp byte(value, path),
    do: {:error, "#{path} must be an integer in [0, 255], got #{V.show(value)}"}

  defp tilt(value, _path) when is_number(value) and abs(value) <= @tilt_max,
    do: {:ok, value * 1.0 + 0.0}

  defp tilt(value, path),
    do:
      {:error, "#{path} must be a number in [-0.7854, 0.7854] (rad, ±45°), got #{V.show(value)}"}

  defp some_axis(payload) do
    if map_size(payload) > 0,
      do: :ok,
      else: {:error, "autopilot needs depth and/or heading (a setpoint, \"hold\" or null)"}
  end

  defp setpoint(payload, key, check) do
    case Map.fetch(payload, key) do
      :error -> {:ok, :unchanged}
      {:ok, nil} -> {:ok, nil}
      {:ok, "hold"} -> {:ok, :hold}
      {:ok, value} -> check.(value, key)
    end
  end

  defp depth(value, _path) when is_number(value) and value >= 0 and value <= @max_depth,
    do: {:ok, value * 1.0 + 0.0}

  defp depth(value, path),
    do:
      {:error,
       "#{path} must be a depth in [0, #{@max_depth}] m, \"hold\" or null, got #{V.show(value)}"}

  defp heading(value, _path) when is_number(value) and abs(value) <= @two_pi,
    do: {:ok, PID.wrap_2pi(value)}

  defp heading(value, path),
    do:
      {:error,
       "#{path} must be a heading in [-6.2832, 6.2832] rad, \"hold\" or null, " <>
         "got #{V.show(value)}"}

  defp mission_action("start"), do: :start
  defp mission_action("plan"), do: :plan
  defp mission_action("pause"), do: :pause
  defp mission_action("resume"), do: :resume
  defp mission_action("abort"), do: :abort
end
