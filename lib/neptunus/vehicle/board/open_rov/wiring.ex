defmodule Neptunus.Vehicle.Board.OpenROV.Wiring do
  @moduledoc """
  How a vehicle's thrusters are wired to the board: which motor is in which position of the
  `go(m1,m2,m3,flag);` command, which motors turn the opposite way, and the flag.
  Pure; configuration per vehicle (`NEPTUNUS_WIRING`, see `Neptunus.Config.Vehicles`).

  Thruster values everywhere else are in the physical sense (positive pushes forward for
  port/starboard, down for vertical, see `Neptunus.Allocation`); this module is the only
  place that knows the board's view.

  **Default (the thesis' Neptunus):** order port, vertical, starboard (ch. 8.4); the port
  motor reversed — a wiring error made it turn the other way, `go(1700,1700,1700,1)` pushed the
  port thruster backwards (ch. 3.4 and 13); flag 1, as the thesis ran every test.
  Written `-port/vertical/starboard/direct`.

  **Motor modifiers.** The OpenROV firmware (2.5.2 on, `Motor::goms`) multiplies each motor's
  offset from neutral by a modifier — `forward div 100` above neutral, `reverse div 100`
  below — and its defaults are 100 forward and **200 reverse**: a reversed motor gets twice
  the pulse offset of a forward one, and the vehicle yaws on a straight surge. The board link
  sets the modifiers (`mtrmod1(…);` forward, `mtrmod2(…);` reverse, in `go()` order, see
  `modifier_commands/1`) at every (re)open and after a board reset. Default 100 and 100 for
  every motor (equal commands, equal pulse offsets); a motor whose thruster is weaker one way
  can be given other values, written after the motor as `:FORWARD:REVERSE` in percent, e.g.
  `-port:100:200/vertical/starboard`. The firmware divides them by 100 as integers, so only
  multiples of 100 (100..1000) are accepted.

  **The flag** (`go()`'s 4th argument). The OpenROV 2.5.x and 30.x firmware only store it as
  "bypass smoothing", which nothing reads since the smoothing was removed (September 2014): the
  values of a `go()` take effect at the firmware's next 50 ms thruster tick either way. It is
  kept because older firmware ramped with 0 (every 50 ms at most 40 µs further from neutral)
  and applied the values at once with 1: `direct` sends 1 (the default, what the thesis'
  vehicle ran), `ramp` sends 0; on 2.5/30 firmware both behave the same. `smooth` and
  `nosmooth` are refused: the thesis' word for the flag meant the opposite of what the old
  firmware did with it.

      iex> alias Neptunus.Vehicle.Board.OpenROV.Wiring
      iex> w = Wiring.default()
      iex> Wiring.to_us(w, %{port: 0.5, vertical: 0.0, starboard: 0.5})
      {1250, 1500, 1750}
      iex> Wiring.go_command(w, %{port: 0.5, vertical: 0.0, starboard: 0.5})
      "go(1250,1500,1750,1);"
  """

  alias Neptunus.Allocation
  alias Neptunus.Vehicle.Board.OpenROV

  @motors [:port, :vertical, :starboard]

  @ambiguous "direct or ramp: smooth/nosmooth meant the opposite of what the OpenROV " <>
               "firmware does (go()'s 4th argument 1 bypasses its smoothing); direct sends 1, " <>
               "ramp sends 0"

  @enforce_keys [:order, :reversed, :direct]
  defstruct [:order, :reversed, :direct, modifiers: %{}]

  @typedoc """
  * `order` — the three motors in `go()` order, each of `:port`, `:vertical`, `:starboard`
  * `reversed` — the motors whose command is negated (propeller or wiring reversed)
  * `direct` — the 4th argument of `go()`: `true` → 1, `false` → 0 (no effect on 2.5/30
    firmware, see above)
  * `modifiers` — `{forward, reverse}` in percent per motor; a motor not listed has 100, 100
  """
  @type motor :: :port | :vertical | :starboard
  @type modifier :: 100..1000
  @type t :: %__MODULE__{
          order: [motor()],
          reversed: [motor()],
          direct: boolean(),
          modifiers: %{optional(motor()) => {modifier(), modifier()}}
        }

  @doc """
  The motor modifiers in `go()` order: `{forward, reverse}` with three percentages each.

      iex> alias Neptunus.Vehicle.Board.OpenROV.Wiring
      iex> Wiring.modifiers(Wiring.default())
      {{100, 100, 100}, {100, 100, 100}}
  """
  @spec modifiers(t()) ::
          {{modifier(), modifier(), modifier()}, {modifier(), modifier(), modifier()}}
  def modifiers(%__MODULE__{order: [a, b, c]} = wiring) do
    [{fa, ra}, {fb, rb}, {fc, rc}] =
      Enum.map([a, b, c], &Map.get(wiring.modifiers, &1, {100, 100}))

    {{fa, fb, fc}, {ra, rb, rc}}
  end

  @doc """
  The commands that set the board's motor modifiers: `mtrmod1` (forward) and `mtrmod2`
  (reverse).

      iex> alias Neptunus.Vehicle.Board.OpenROV.Wiring
      iex> Wiring.modifier_commands(Wiring.default())
      ["mtrmod1(100,100,100);", "mtrmod2(100,100,100);"]
  """
  @spec modifier_commands(t()) :: [binary()]
  def modifier_commands(%__MODULE__{} = wiring) do
    {forward, reverse} = modifiers(wiring)
    [OpenROV.Protocol.mtrmod1(forward), OpenROV.Protocol.mtrmod2(reverse)]
  end

  @doc "The thesis' Neptunus: `-port/vertical/starboard/direct`."
  @spec default() :: t()
  def default, do: %__MODULE__{order: @motors, reversed: [:port], direct: true}

  @doc """
  The motors' pulse widths in `go()` order for physical thruster values in [-1, 1].

      iex> alias Neptunus.Vehicle.Board.OpenROV.Wiring
      iex> w = %Wiring{order: [:starboard, :port, :vertical], reversed: [], direct: false}
      iex> Wiring.to_us(w, %{port: 1.0, vertical: -1.0, starboard: 0.0})
      {1500, 2000, 1000}
  """
  @spec to_us(t(), Allocation.thrusters()) ::
          {OpenROV.Protocol.us(), OpenROV.Protocol.us(), OpenROV.Protocol.us()}
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
    do: OpenROV.Protocol.go(to_us(wiring, thrusters), wiring.direct)

  @doc """
  The board's side: physical thruster values from the pulse widths of a `go()` (the SITL
  board uses this; quantised to 1/500).

      iex> alias Neptunus.Vehicle.Board.OpenROV.Wiring
      iex> Wiring.from_us(Wiring.default(), {1250, 1500, 1750})
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
  optionally prefixed with `-` when reversed and followed by `:FORWARD:REVERSE` modifiers
  (see above), then optionally `/direct` or `/ramp` (default direct; see the flag above).

      iex> alias Neptunus.Vehicle.Board.OpenROV.Wiring
      iex> Wiring.parse("-port/vertical/starboard")
      {:ok, Wiring.default()}
      iex> Wiring.parse("starboard/-vertical/port/ramp")
      {:ok, %Wiring{order: [:starboard, :vertical, :port], reversed: [:vertical], direct: false}}
      iex> {:ok, w} = Wiring.parse("-port:100:200/vertical/starboard")
      iex> Wiring.modifiers(w)
      {{100, 100, 100}, {200, 100, 100}}
      iex> {:error, "motor modifiers are percentages 100..1000 in steps of 100" <> _} =
      ...>   Wiring.parse("port:150:100/vertical/starboard")
      iex> Wiring.parse("port/port/starboard")
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
         reversed: for({motor, true, _} <- signed, do: motor),
         direct: direct,
         modifiers:
           for({motor, _, mods} <- signed, mods != {100, 100}, into: %{}, do: {motor, mods})
       }}
    end
  end

  defp motors(names, text) do
    signed =
      Enum.map(names, fn name ->
        {reversed, name} =
          case name do
            "-" <> name -> {true, name}
            name -> {false, name}
          end

        case String.split(name, ":") do
          [name] ->
            {:ok, {motor(name), reversed, {100, 100}}}

          [name, f, r] ->
            with {:ok, mods} <- modifier_pair(f, r), do: {:ok, {motor(name), reversed, mods}}

          _ ->
            {:error, "a motor is NAME or NAME:FORWARD:REVERSE (got #{inspect(name)})"}
        end
      end)

    case Enum.find(signed, &match?({:error, _}, &1)) do
      nil ->
        signed = Enum.map(signed, fn {:ok, m} -> m end)

        if Enum.sort(Enum.map(signed, &elem(&1, 0))) == Enum.sort(@motors),
          do: {:ok, signed},
          else: {:error, "each of port, vertical, starboard exactly once (got #{inspect(text)})"}

      error ->
        error
    end
  end

  defp modifier_pair(f, r) do
    with {:ok, f} <- modifier(f), {:ok, r} <- modifier(r), do: {:ok, {f, r}}
  end

  defp modifier(text) do
    case Integer.parse(text) do
      {n, ""} when n in 100..1000 and rem(n, 100) == 0 ->
        {:ok, n}

      _ ->
        {:error,
         "motor modifiers are percentages 100..1000 in steps of 100 (the firmware divides " <>
           "them by 100 as integers), not #{inspect(text)}"}
    end
  end

  defp motor("port"), do: :port
  defp motor("vertical"), do: :vertical
  defp motor("starboard"), do: :starboard
  defp motor(_), do: nil

  @doc """
  The configuration syntax of a wiring (the inverse of `parse/1`).

      iex> alias Neptunus.Vehicle.Board.OpenROV.Wiring
      iex> Wiring.to_string(Wiring.default())
      "-port/vertical/starboard/direct"
  """
  @spec to_string(t()) :: String.t()
  def to_string(%__MODULE__{} = wiring) do
    motors =
      Enum.map(wiring.order, fn motor ->
        sign = if motor in wiring.reversed, do: "-", else: ""

        mods =
          case Map.get(wiring.modifiers, motor, {100, 100}) do
            {100, 100} -> ""
            {f, r} -> ":#{f}:#{r}"
          end

        "#{sign}#{motor}#{mods}"
      end)

    Enum.join(motors ++ [if(wiring.direct, do: "direct", else: "ramp")], "/")
  end
end
