defmodule Neptunus.GCS.Modes do
  @moduledoc """
  A vehicle's control state as a MAVLink flight mode (HEARTBEAT's `custom_mode`) and back
  (pure): what a ground station shows and sets.

  The numbers are ArduSub's where the meaning is the same — so Cockpit and anything else
  that names ArduSub's modes shows them right — and Neptunus' own above 100:

  | custom_mode | name | control state |
  |---|---|---|
  | 19 | `MANUAL` | motion, no autopilot |
  | 0 | `STABILIZE` | motion, heading hold |
  | 2 | `ALT_HOLD` | motion, depth and heading hold |
  | 16 | `POSHOLD` | DP (position hold; depth and heading without a position source) |
  | 100 | `DEPTH_HOLD` | motion, depth hold without heading hold (Neptunus) |
  | 101 | `THRUSTERS` | manual per-thruster mode (Neptunus; shown, not set: MANUAL_CONTROL cannot drive single thrusters) |

  Setting a mode is a sequence of the browser's control commands (`commands/2`): the control
  mode first when it changes (which stops the thrusters, as on the operator page), then the
  autopilots with `"hold"` (engaged at the depth and heading the vehicle has). An ArduSub
  vehicle (the `mavlink` board) reports its own flight mode's number, and setting one goes
  through the same `autopilot` command its operator page uses (its board maps it to ArduSub's
  mode; what it cannot fly, it refuses with its reason).
  """

  @manual 19
  @stabilize 0
  @alt_hold 2
  @poshold 16
  @depth_hold 100
  @thrusters 101

  @names %{
    @manual => "MANUAL",
    @stabilize => "STABILIZE",
    @alt_hold => "ALT_HOLD",
    @poshold => "POSHOLD",
    @depth_hold => "DEPTH_HOLD",
    @thrusters => "THRUSTERS"
  }

  # ArduSub's own modes, by name (a mavlink vehicle reports the one it is in)
  @ardusub %{
    "STABILIZE" => 0,
    "ACRO" => 1,
    "ALT_HOLD" => 2,
    "AUTO" => 3,
    "GUIDED" => 4,
    "CIRCLE" => 7,
    "SURFACE" => 9,
    "POSHOLD" => 16,
    "MANUAL" => 19,
    "MOTOR_DETECT" => 20,
    "SURFTRAK" => 21
  }

  @type command :: {String.t(), map()}

  @doc "Neptunus' modes: `%{custom_mode => name}`."
  @spec names() :: %{non_neg_integer() => String.t()}
  def names, do: @names

  @doc """
  The `custom_mode` of a control state (telemetry's `control`: `%{mode, autopilot: %{depth,
  heading}}`), or, for a mavlink vehicle, of ArduSub's mode name (`link.mavlink.mode`).

      iex> Neptunus.GCS.Modes.current(%{mode: "motion", autopilot: %{depth: 2.0, heading: 1.0}}, nil)
      2
      iex> Neptunus.GCS.Modes.current(%{mode: "motion", autopilot: %{depth: nil, heading: nil}}, nil)
      19
      iex> Neptunus.GCS.Modes.current(nil, "ACRO")
      1
  """
  @spec current(map() | nil, String.t() | nil) :: non_neg_integer()
  def current(_control, ardusub) when is_map_key(@ardusub, ardusub),
    do: Map.fetch!(@ardusub, ardusub)

  def current(%{mode: "manual"}, _), do: @thrusters
  def current(%{mode: "dp"}, _), do: @poshold

  def current(%{mode: "motion", autopilot: autopilot}, _) do
    case {autopilot[:depth] != nil, autopilot[:heading] != nil} do
      {true, true} -> @alt_hold
      {true, false} -> @depth_hold
      {false, true} -> @stabilize
      {false, false} -> @manual
    end
  end

  def current(_control, _ardusub), do: @manual

  @doc """
  The control commands (`Neptunus.Vehicle.Control.command/3`'s events and payloads) that
  take the vehicle from control state `control` to `custom_mode`, or why not.

      iex> Neptunus.GCS.Modes.commands(2, %{mode: "motion"})
      {:ok, [{"autopilot", %{"depth" => "hold", "heading" => "hold"}}]}
      iex> Neptunus.GCS.Modes.commands(19, %{mode: "dp"})
      {:ok, [{"set_control_mode", %{"mode" => "motion"}}, {"autopilot", %{"depth" => nil, "heading" => nil}}]}
      iex> Neptunus.GCS.Modes.commands(101, %{mode: "motion"})
      {:error, "THRUSTERS (manual per-thruster mode) cannot be flown with MANUAL_CONTROL: set it on the operator page"}
  """
  @spec commands(integer(), map() | nil) :: {:ok, [command()]} | {:error, String.t()}
  def commands(@poshold, control), do: {:ok, control_mode(control, "dp")}

  def commands(@thrusters, _control),
    do:
      {:error,
       "THRUSTERS (manual per-thruster mode) cannot be flown with MANUAL_CONTROL: set it on " <>
         "the operator page"}

  def commands(mode, control) when is_map_key(@names, mode) do
    {depth, heading} =
      case mode do
        @manual -> {nil, nil}
        @stabilize -> {nil, "hold"}
        @alt_hold -> {"hold", "hold"}
        @depth_hold -> {"hold", nil}
      end

    {:ok,
     control_mode(control, "motion") ++
       [{"autopilot", %{"depth" => depth, "heading" => heading}}]}
  end

  def commands(mode, _control) do
    known = @names |> Enum.sort() |> Enum.map_join(", ", fn {n, name} -> "#{n} #{name}" end)
    {:error, "no flight mode #{mode} here: #{known}"}
  end

  defp control_mode(%{mode: mode}, mode), do: []
  defp control_mode(_control, mode), do: [{"set_control_mode", %{"mode" => mode}}]
end
