defmodule Neptunus.Wiring do
  @moduledoc """
  How a vehicle's thrusters are wired to the board: which motor is in which position of the
  `go(m1,m2,m3,flag);` command, which motors turn the opposite way, and the flag.
  Pure; configuration per vehicle (`NEPTUNUS_WIRING`, see `Neptunus.Config`).

  Thruster values everywhere else are in the physical sense (positive pushes forward for
  port/starboard, down for vertical, see `Neptunus.Allocation`); this module is the only
  place that knows the board's view.

  **Default (the thesis' Neptunus):** order port, vertical, starboard (ch. 8.4); the port
  motor reversed — a wiring error made it turn the other way, `go(1700,1700,1700,1)` pushed the
  port thruster backwards (ch. 3.4 and 13); flag 1, as the thesis ran every test.
  Written `-port/vertical/starboard/direct`.

  **The flag** (`go()`'s 4th argument). The thesis calls it "activate the smoothing filter",
  but the OpenROV firmware (`Thrusters2X1.cpp`: `if (command.args[4] == 1)
  bypasssmoothing=true;`) reads `1` as *bypass* smoothing: the motors take the new values at
  once. With `0` the firmware ramps: every 50 ms each motor moves at most 40 µs further from
  neutral, drops to neutral first when the direction reverses, and reduces power at once. So
  the configuration names what happens, not the thesis' word: `direct` (1, the default and
  what the thesis' vehicle ran) or `ramp` (0). `smooth` and `nosmooth` are refused: they
  meant the opposite of what the firmware does.

      iex> w = Neptunus.Wiring.default()
      iex> Neptunus.Wiring.to_us(w, %{port: 0.5, vertical: 0.0, starboard: 0.5})
      {1250, 1500, 1750}
      iex> Neptunus.Wiring.go_command(w, %{port: 0.5, vertical: 0.0, starboard: 0.5})
      "go(1250,1500,1750,1);"
  """

  alias Neptunus.{Allocation, Protocol.OpenROV}

  @motors [:port, :vertical, :starboard]

  @ambiguous "direct or ramp: smooth/nosmooth meant the opposite of what the OpenROV " <>
               "firmware does (go()'s 4th argument 1 bypasses its smoothing); direct sends 1, " <>
               "ramp sends 0"

  @enforce_keys [:order, :reversed, :direct]
  defstruct [:order, :reversed, :direct]

  @typedoc """
  * `order` — the three motors in `go()` order, each of `:port`, `:vertical`, `:starboard`
  * `reversed` — the motors whose command is negated (propeller or wiring reversed)
  * `direct` — the 4th argument of `go()`: `true` → 1 (the firmware applies the values at
    once), `false` → 0 (the firmware ramps them)
  """
  @type motor :: :port | :vertical | :starboard
  @type t :: %__MODULE__{order: [motor()], reversed: [motor()], direct: boolean()}

  @doc "The thesis' Neptunus: `-port/vertical/starboard/direct`."
  @spec default() :: t()
  def default, do: %__MODULE__{order: @motors, reversed: [:port], direct: true}

  @doc """
  The motors' pulse widths in `go()` order for physical thruster values in [-1, 1].

      iex> w = %Neptunus.Wiring{order: [:starboard, :port, :vertical], reversed: [], direct: false}
      iex> Neptunus.Wiring.to_us(w, %{port: 1.0, vertical: -1.0, starboard: 0.0})
      {1500, 2000, 1000}
  """
  @spec to_us(t(), Allocation.thrusters()) :: {OpenROV.us(), OpenROV.us(), OpenROV.us()}
  def to_us(%__MODULE__{order: [a, b, c]} = wiring, thrusters) do
    {motor_us(wiring, thrusters, a), motor_us(wiring, thrusters, b),
     motor_us(wiring, thrusters, c)}
  end

  defp motor_us(wiring, thrusters, motor) do
    value = Map.fetch!(thrusters, motor)
    Allocation.to_us(if motor in wiring.reversed, do: -value, else: value)
  end

  @doc "The `go()` command for physical thruster values."
  @spec go_command(t(), Allocation.thrusters()) :: binary()
  def go_command(%__MODULE__{} = wiring, thrusters),
    do: OpenROV.go(to_us(wiring, thrusters), wiring.direct)

  @doc """
  The board's side: physical thruster values from the pulse widths of a `go()` (the SITL
  board uses this; quantised to 1/500).

      iex> Neptunus.Wiring.from_us(Neptunus.Wiring.default(), {1250, 1500, 1750})
      %{port: 0.5, vertical: 0.0, starboard: 0.5}
  """
  @spec from_us(t(), {integer(), integer(), integer()}) :: Allocation.thrusters()
  def from_us(%__MODULE__{order: order, reversed: reversed}, {a, b, c}) do
    order
    |> Enum.zip([a, b, c])
    |> Map.new(fn {motor, us} ->
      value = (us - 1500) / 500
      {motor, if(motor in reversed, do: -value, else: value) + 0.0}
    end)
  end

  @doc """
  Parses the configuration syntax: the three motors in `go()` order separated by `/`, each
  optionally prefixed with `-` when reversed, then optionally `/direct` or `/ramp`
  (default direct; see the flag above).

      iex> Neptunus.Wiring.parse("-port/vertical/starboard")
      {:ok, Neptunus.Wiring.default()}
      iex> Neptunus.Wiring.parse("starboard/-vertical/port/ramp")
      {:ok, %Neptunus.Wiring{order: [:starboard, :vertical, :port], reversed: [:vertical], direct: false}}
      iex> Neptunus.Wiring.parse("port/port/starboard")
      {:error, "each of port, vertical, starboard exactly once (got \\"port/port/starboard\\")"}
  """
  @spec parse(String.t()) :: {:ok, t()} | {:error, String.t()}
  def parse(text) when is_binary(text) do
    parts = text |> String.trim() |> String.split("/") |> Enum.map(&String.trim/1)

    {motors, direct} =
      case parts do
        [a, b, c, "direct"] -> {[a, b, c], {:ok, true}}
        [a, b, c, "ramp"] -> {[a, b, c], {:ok, false}}
        [a, b, c] -> {[a, b, c], {:ok, true}}
        [_, _, _, word] when word in ["smooth", "nosmooth"] -> {[], {:error, @ambiguous}}
        [_, _, _, other] -> {[], {:error, "direct or ramp, not #{inspect(other)}"}}
        _ -> {[], {:error, "three motors separated by / (got #{inspect(text)})"}}
      end

    with {:ok, direct} <- direct,
         {:ok, signed} <- motors(motors, text) do
      {:ok,
       %__MODULE__{
         order: Enum.map(signed, &elem(&1, 0)),
         reversed: for({motor, true} <- signed, do: motor),
         direct: direct
       }}
    end
  end

  defp motors(names, text) do
    signed =
      Enum.map(names, fn
        "-" <> name -> {motor(name), true}
        name -> {motor(name), false}
      end)

    if Enum.sort(Enum.map(signed, &elem(&1, 0))) == Enum.sort(@motors),
      do: {:ok, signed},
      else: {:error, "each of port, vertical, starboard exactly once (got #{inspect(text)})"}
  end

  defp motor("port"), do: :port
  defp motor("vertical"), do: :vertical
  defp motor("starboard"), do: :starboard
  defp motor(_), do: nil

  @doc """
  The configuration syntax of a wiring (the inverse of `parse/1`).

      iex> Neptunus.Wiring.to_string(Neptunus.Wiring.default())
      "-port/vertical/starboard/direct"
  """
  @spec to_string(t()) :: String.t()
  def to_string(%__MODULE__{} = wiring) do
    motors = Enum.map(wiring.order, &if(&1 in wiring.reversed, do: "-#{&1}", else: "#{&1}"))
    Enum.join(motors ++ [if(wiring.direct, do: "direct", else: "ramp")], "/")
  end
end
