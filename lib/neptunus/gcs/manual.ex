defmodule Neptunus.GCS.Manual do
  @moduledoc """
  A ground station's stick input as Control's motion demand (pure): MANUAL_CONTROL (and
  RC_CHANNELS_OVERRIDE) → `%{surge, heave, yaw}`, each in [-1, 1], the payload a browser's
  `thrust` carries in motion mode.

  The convention is ArduSub's, which QGroundControl, Cockpit and the Blue Robotics tools
  follow for a submarine:

    * MANUAL_CONTROL: `x` forward −1000..1000, `y` lateral, `z` vertical 0..1000 with 500
      neutral and above 500 *up*, `r` yaw to starboard −1000..1000;
    * RC_CHANNELS_OVERRIDE: channel 5 forward, 6 lateral, 3 throttle (up above 1500), 4 yaw,
      1100..1900 µs with 1500 neutral; 0 and 65535 (no override) count as neutral.

  Our heave is positive *down*, so `heave = (500 − z) / 500`. Lateral (`y`, channel 6) is not
  used yet: Control takes surge, heave and yaw; sway is one line in `axes/1` when it takes
  a body-frame demand.
  """

  @type axes :: %{surge: float(), heave: float(), yaw: float()}

  @doc """
  The motion demand of a MANUAL_CONTROL's fields.

      iex> Neptunus.GCS.Manual.axes(%{x: 500, y: 0, z: 500, r: -1000})
      %{surge: 0.5, heave: 0.0, yaw: -1.0}
      iex> Neptunus.GCS.Manual.axes(%{x: 0, y: 0, z: 1000, r: 0}).heave
      -1.0
      iex> Neptunus.GCS.Manual.axes(%{x: 32767, y: 0, z: -5000, r: 0})
      %{surge: 1.0, heave: 1.0, yaw: 0.0}
  """
  @spec axes(%{:x => integer(), :z => integer(), :r => integer(), optional(atom()) => term()}) ::
          axes()
  def axes(%{x: x, z: z, r: r}) do
    %{
      surge: clamp(x / 1000),
      heave: clamp((500 - z) / 500),
      yaw: clamp(r / 1000)
    }
  end

  @doc """
  The motion demand of an RC_CHANNELS_OVERRIDE's fields (ArduSub's channel map).

      iex> Neptunus.GCS.Manual.rc_axes(%{chan3_raw: 1900, chan4_raw: 1500, chan5_raw: 1700})
      %{surge: 0.5, heave: -1.0, yaw: 0.0}
      iex> Neptunus.GCS.Manual.rc_axes(%{chan3_raw: 0, chan4_raw: 65535, chan5_raw: 1500})
      %{surge: 0.0, heave: 0.0, yaw: 0.0}
  """
  @spec rc_axes(map()) :: axes()
  def rc_axes(channels) do
    %{
      surge: pwm(channels.chan5_raw),
      heave: 0.0 - pwm(channels.chan3_raw),
      yaw: pwm(channels.chan4_raw)
    }
  end

  @doc "Whether a demand is neutral (every axis 0)."
  @spec neutral?(axes()) :: boolean()
  def neutral?(axes), do: Enum.all?(Map.values(axes), &(&1 == 0))

  defp pwm(us) when us in [0, 65_535], do: 0.0
  defp pwm(us), do: clamp((us - 1500) / 400)

  # exact zeros stay 0.0 (never -0.0: a neutral demand compares equal to neutral)
  defp clamp(v), do: (v |> max(-1.0) |> min(1.0)) + 0.0
end
