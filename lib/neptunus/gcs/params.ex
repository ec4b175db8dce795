defmodule Neptunus.GCS.Params do
  @moduledoc """
  A vehicle's tunables as MAVLink parameters (pure): their names, values and what setting
  one means. Every value travels as a float (`MAV_PARAM_TYPE_REAL32`, 9).

  | parameter | unit | what | set by |
  |---|---|---|---|
  | `PILOT_GAIN` | 0..1 | the gain k on the pilot's axes | the pilot (`set_gain`) |
  | `LIGHTS` | 0..255 | lights | the pilot (`set_lights`) |
  | `CAM_TILT_DEG` | ° | camera tilt, −45..45 | the pilot (`set_tilt`) |
  | `DEPTH_KP`, `DEPTH_KI`, `DEPTH_KD` | | the depth autopilot's PID gains | the pilot or the main station (the tuning panel's `set_tuning`) |
  | `HDG_KP`, `HDG_KI`, `HDG_KD` | | the heading autopilot's | the pilot or the main station |
  | `DEPTH_RATE_MAX`, `DEPTH_ACC_MAX` | m/s, m/s² | the depth reference's limits | read-only (configuration) |
  | `HDG_RATE_MAX`, `HDG_ACC_MAX` | °/s, °/s² | the heading reference's | read-only |
  | `DEADMAN_MS`, `REQ_TIMEOUT_MS`, `TAKEOVER_MS` | ms | the helm's timing | read-only (configuration) |
  | `WIRE_PORT_POS`, `WIRE_PORT_REV` (and `VERT`, `STBD`) | 1..3, 0/1 | a `uart`/`sitl` vehicle's thruster wiring (`go()` position, reversed) | read-only |

  Setting a parameter is the same command, with the same validation and storage, as on the
  pages: the operator page's controls (`Neptunus.Vehicle.Control.command/3` through the helm)
  and the developer page's tuning panel (`Neptunus.Vehicle.Control.tune/2`: validated by
  `Neptunus.Control.Tuning`, stored per vehicle). What is read-only stays so: the limits and
  the helm's timing are the node's configuration, and rewiring thrusters on a live vehicle
  (which motor a command drives) is never safe.
  """

  @real32 9

  @gains [
    {"DEPTH_KP", "depth", "kp"},
    {"DEPTH_KI", "depth", "ki"},
    {"DEPTH_KD", "depth", "kd"},
    {"HDG_KP", "heading", "kp"},
    {"HDG_KI", "heading", "ki"},
    {"HDG_KD", "heading", "kd"}
  ]

  @type value :: float()
  @type param :: %{name: String.t(), value: value()}
  @type set ::
          {:control, String.t(), map()}
          | {:tune, map()}

  @typedoc """
  What the values are read from: the vehicle's control state (telemetry's `control`), its
  autopilot tuning (`Neptunus.Vehicle.Control.tuning/1`'s `gains`), the references' limits
  (`Neptunus.Vehicle.Control.limits/1`), the helm (its broadcast) and the board's wiring
  (nil unless a `uart` or `sitl` vehicle).
  """
  @type sources :: %{
          control: map() | nil,
          gains: map() | nil,
          limits: map() | nil,
          helm: map() | nil,
          wiring: Neptunus.Vehicle.Board.OpenROV.Wiring.t() | nil
        }

  @doc "The MAV_PARAM_TYPE of every parameter (REAL32)."
  @spec type() :: 9
  def type, do: @real32

  @doc """
  The parameters and their values, in a fixed order (their index): those whose source is
  not known are left out.
  """
  @spec list(sources()) :: [param()]
  def list(sources) do
    control = sources.control || %{}

    control_params = [
      {"PILOT_GAIN", control[:gain]},
      {"LIGHTS", control[:lights]},
      {"CAM_TILT_DEG", control[:tilt] && control[:tilt] * 180 / :math.pi()}
    ]

    gain_params =
      for {name, axis, key} <- @gains do
        {name, get_in(sources.gains || %{}, [axis, key])}
      end

    limits = sources.limits || %{}

    limit_params = [
      {"DEPTH_RATE_MAX", get_in(limits, [:depth, :rate])},
      {"DEPTH_ACC_MAX", get_in(limits, [:depth, :accel])},
      {"HDG_RATE_MAX", degrees(get_in(limits, [:heading, :rate]))},
      {"HDG_ACC_MAX", degrees(get_in(limits, [:heading, :accel]))}
    ]

    helm = sources.helm || %{}

    helm_params = [
      {"DEADMAN_MS", helm[:deadman_ms]},
      {"REQ_TIMEOUT_MS", helm[:request_timeout_ms]},
      {"TAKEOVER_MS", helm[:takeover_ms]}
    ]

    (control_params ++ gain_params ++ limit_params ++ helm_params ++ wiring(sources.wiring))
    |> Enum.filter(fn {_name, value} -> is_number(value) end)
    |> Enum.map(fn {name, value} -> %{name: name, value: value * 1.0} end)
  end

  defp degrees(nil), do: nil
  defp degrees(rad), do: rad * 180 / :math.pi()

  defp wiring(%Neptunus.Vehicle.Board.OpenROV.Wiring{order: order, reversed: reversed}) do
    for {motor, short} <- [port: "PORT", vertical: "VERT", starboard: "STBD"],
        position = Enum.find_index(order, &(&1 == motor)),
        position != nil,
        {suffix, value} <- [{"POS", position + 1}, {"REV", if(motor in reversed, do: 1, else: 0)}] do
      {"WIRE_#{short}_#{suffix}", value}
    end
  end

  defp wiring(_), do: []

  @doc """
  What setting parameter `name` to `value` means: a control command (`{:control, event,
  payload}`, the pilot's), a tuning (`{:tune, payload}`, the pilot's or the main
  station's), or why it cannot be set. Values are checked by the command itself, as from
  the pages.

      iex> Neptunus.GCS.Params.set("LIGHTS", 128.0)
      {:control, "set_lights", %{"value" => 128}}
      iex> Neptunus.GCS.Params.set("DEPTH_KP", 3.5)
      {:tune, %{"depth" => %{"kp" => 3.5}}}
      iex> Neptunus.GCS.Params.set("DEADMAN_MS", 100.0)
      {:error, "DEADMAN_MS is read-only: the node's configuration"}
      iex> Neptunus.GCS.Params.set("LIGHTS", 12.5)
      {:error, "LIGHTS must be a whole number in 0..255, got 12.5"}
  """
  @spec set(String.t(), number() | atom()) :: set() | {:error, String.t()}
  def set(_name, value) when not is_number(value),
    do: {:error, "a parameter's value must be a number, got #{inspect(value)}"}

  def set("PILOT_GAIN", value), do: {:control, "set_gain", %{"value" => value}}

  def set("LIGHTS", value) do
    if value == Float.round(value * 1.0) and value >= 0 and value <= 255,
      do: {:control, "set_lights", %{"value" => trunc(value)}},
      else: {:error, "LIGHTS must be a whole number in 0..255, got #{value}"}
  end

  def set("CAM_TILT_DEG", value),
    do: {:control, "set_tilt", %{"value" => value * :math.pi() / 180}}

  def set(name, value) do
    case List.keyfind(@gains, name, 0) do
      {_, axis, key} ->
        {:tune, %{axis => %{key => value}}}

      nil ->
        cond do
          name in ~w(DEPTH_RATE_MAX DEPTH_ACC_MAX HDG_RATE_MAX HDG_ACC_MAX DEADMAN_MS REQ_TIMEOUT_MS TAKEOVER_MS) ->
            {:error, "#{name} is read-only: the node's configuration"}

          String.starts_with?(name, "WIRE_") ->
            {:error,
             "#{name} is read-only: rewiring thrusters on a live vehicle is not safe " <>
               "(NEPTUNUS_WIRING at boot)"}

          true ->
            {:error, "no parameter #{name}"}
        end
    end
  end

  @doc "Whether `name` is a parameter that only the pilot may set (the others: tuning)."
  @spec pilot_only?(String.t()) :: boolean()
  def pilot_only?(name), do: name in ~w(PILOT_GAIN LIGHTS CAM_TILT_DEG)
end
