defmodule Neptunus.GCS.Manual do
  @moduledoc """
  A ground station's stick input as Control's motion demand (pure): MANUAL_CONTROL (and
  RC_CHANNELS_OVERRIDE) → `%{surge, sway, heave, yaw}`, each in [-1, 1], and the payload a
  browser's `thrust` carries in motion mode (`thrust_payload/3`).

  The convention is ArduSub's, which QGroundControl, Cockpit and the Blue Robotics tools
  follow for a submarine:

    * MANUAL_CONTROL: `x` forward −1000..1000, `y` lateral, `z` vertical 0..1000 with 500
      neutral and above 500 *up*, `r` yaw to starboard −1000..1000;
    * RC_CHANNELS_OVERRIDE: channel 5 forward, 6 lateral, 3 throttle (up above 1500), 4 yaw,
      1100..1900 µs with 1500 neutral; 0 and 65535 (no override) count as neutral.

  Our heave is positive *down*, so `heave = (500 − z) / 500`. Lateral (`y`, channel 6) is
  sway, to starboard: the thrust carries it only to a vehicle that can sway (`sway` in its
  board's axes, `Neptunus.Vehicle.Board.capabilities/1`: an ArduSub vehicle whose frame
  strafes, a simulated `neptunus-sway`), as a browser's does; for any other vehicle it is left out — ignored,
  never refused (a stick's lateral axis is never exactly centred).
  """

  @type axes :: %{surge: float(), sway: float(), heave: float(), yaw: float()}

  @doc """
  The motion demand of a MANUAL_CONTROL's fields.

      iex> Neptunus.GCS.Manual.axes(%{x: 500, y: -250, z: 500, r: -1000})
      %{surge: 0.5, sway: -0.25, heave: 0.0, yaw: -1.0}
      iex> Neptunus.GCS.Manual.axes(%{x: 0, y: 0, z: 1000, r: 0}).heave
      -1.0
      iex> Neptunus.GCS.Manual.axes(%{x: 32767, y: -32768, z: -5000, r: 0})
      %{surge: 1.0, sway: -1.0, heave: 1.0, yaw: 0.0}
  """
  @spec axes(%{
          :x => integer(),
          :y => integer(),
          :z => integer(),
          :r => integer(),
          optional(atom()) => term()
        }) :: axes()
  def axes(%{x: x, y: y, z: z, r: r}) do
    %{
      surge: clamp(x / 1000),
      sway: clamp(y / 1000),
      heave: clamp((500 - z) / 500),
      yaw: clamp(r / 1000)
    }
  end

  @doc """
  The motion demand of an RC_CHANNELS_OVERRIDE's fields (ArduSub's channel map).

      iex> Neptunus.GCS.Manual.rc_axes(%{chan3_raw: 1900, chan4_raw: 1500, chan5_raw: 1700, chan6_raw: 1300})
      %{surge: 0.5, sway: -0.5, heave: -1.0, yaw: 0.0}
      iex> Neptunus.GCS.Manual.rc_axes(%{chan3_raw: 0, chan4_raw: 65535, chan5_raw: 1500, chan6_raw: 0})
      %{surge: 0.0, sway: 0.0, heave: 0.0, yaw: 0.0}
  """
  @spec rc_axes(map()) :: axes()
  def rc_axes(channels) do
    %{
      surge: pwm(channels.chan5_raw),
      sway: pwm(channels.chan6_raw),
      heave: 0.0 - pwm(channels.chan3_raw),
      yaw: pwm(channels.chan4_raw)
    }
  end

  @doc """
  The `thrust` payload of a demand for a vehicle commanded in `vehicle_axes` (its board's
  axes), stamped with the helm's `epoch`: motion mode's `surge`, `heave`, `yaw`, and `sway`
  only when the vehicle can sway — a vehicle without it would refuse the thrust.

      iex> axes = %{surge: 0.5, sway: 0.25, heave: 0.0, yaw: -1.0}
      iex> Neptunus.GCS.Manual.thrust_payload(axes, [:surge, :sway, :heave, :yaw], 3)
      %{"mode" => "motion", "surge" => 0.5, "sway" => 0.25, "heave" => 0.0, "yaw" => -1.0, "epoch" => 3}
      iex> Neptunus.GCS.Manual.thrust_payload(axes, [:surge, :heave, :yaw], 3)
      %{"mode" => "motion", "surge" => 0.5, "heave" => 0.0, "yaw" => -1.0, "epoch" => 3}
  """
  @spec thrust_payload(axes(), [atom()], integer()) :: %{String.t() => term()}
  def thrust_payload(axes, vehicle_axes, epoch) do
    payload = %{
      "mode" => "motion",
      "surge" => axes.surge,
      "heave" => axes.heave,
      "yaw" => axes.yaw,
      "epoch" => epoch
    }

    if :sway in vehicle_axes, do: Map.put(payload, "sway", axes.sway), else: payload
  end

  @doc "Whether a demand is neutral (every axis 0)."
  @spec neutral?(axes()) :: boolean()
  def neutral?(axes), do: Enum.all?(Map.values(axes), &(&1 == 0))

  defp pwm(us) when us in [0, 65_535], do: 0.0
  defp pwm(us), do: clamp((us - 1500) / 400)

  # exact zeros stay 0.0 (never -0.0: a neutral demand compares equal to neutral)
  defp clamp(v), do: (v |> max(-1.0) |> min(1.0)) + 0.0
end
