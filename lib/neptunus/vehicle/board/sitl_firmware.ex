defmodule Neptunus.Vehicle.Board.SITL.Firmware do
  @moduledoc """
  The SITL board's firmware as a pure value: what an OpenROV Arduino does with the command
  bytes it receives and what telemetry it sends. `Neptunus.Vehicle.Board.SITL.Device` runs it
  next to a `Neptunus.Sim`.

    * Commands are `;`-terminated (`Neptunus.Protocol.OpenROV.parse_command/1`); a command with
      bad arguments is ignored and counted, like the firmware's "ignore corrupt data".
    * `go(a,b,c,flag)` sets the motors; the pulse widths are turned into physical thruster
      values with the vehicle's `Neptunus.Wiring` (the SITL board is wired like the real
      vehicle, so a wrong wiring configuration shows in the simulator exactly as it would in
      the water). Flag 1 applies them at once; flag 0 ramps like the OpenROV firmware
      (`Thrusters2X1.cpp`, `smoothAdjustedServoPosition`): every 50 ms each motor moves at
      most 40 µs further from neutral, goes to neutral first when its direction reverses,
      and takes a reduction of power at once (the firmware's dead-zone skip is not modelled).
    * `stop()` drives the motors neutral; `ligt`, `claser`, `tilt` are stored.
    * **Deadman**: `ping(n)` is answered with `pong:n;`. When no ping has come for
      `deadman_ms` (default 3000), the motors go neutral, `deadman:1;` is sent, and `go` is
      ignored until the next ping (then `deadman:0;`).
    * Telemetry: `navdata/2` (`hdgd deap pitc roll yaw fthr`) and `shared_data/2`
      (`vout iout time pres temp`), in the firmware's units.
  """

  alias Neptunus.{Allocation, Wiring}
  alias Neptunus.Protocol.OpenROV

  @max_pending 256
  @surface_mbar 1013.25
  # seawater: ρ g = 1025 kg/m³ · 9.81 m/s² = 100.55 mbar per metre
  @mbar_per_m 100.55
  @water_temp 10.0

  @ramp_ms 50
  @ramp_us 40
  @neutral_us {1500, 1500, 1500}

  @enforce_keys [:wiring, :deadman_ms, :fed_at]
  defstruct [
    :wiring,
    :deadman_ms,
    :fed_at,
    :ramp_at,
    thrusters: %{port: 0.0, vertical: 0.0, starboard: 0.0},
    target_us: @neutral_us,
    out_us: @neutral_us,
    tripped: false,
    pending: "",
    lights: 0,
    laser: 0,
    tilt: 1500,
    last_ping: nil,
    commands: 0,
    bad_commands: 0
  ]

  @typedoc """
  * `thrusters` — physical thruster values in force (from `out_us`)
  * `target_us`, `out_us` — the last `go()`'s pulse widths and those the motors get now (they
    differ while ramping); `ramp_at` — when the next ramp step is due (nil: not ramping)
  * `fed_at` — ms (any monotonic clock) of the last ping, or of the start
  * `tripped` — the deadman has stopped the motors
  * `pending` — command bytes without their `;` yet (at most #{@max_pending})
  * `commands`, `bad_commands` — counters
  """
  @type t :: %__MODULE__{
          wiring: Wiring.t(),
          deadman_ms: pos_integer(),
          fed_at: integer(),
          thrusters: Allocation.thrusters(),
          target_us: {pos_integer(), pos_integer(), pos_integer()},
          out_us: {pos_integer(), pos_integer(), pos_integer()},
          ramp_at: integer() | nil,
          tripped: boolean(),
          pending: binary(),
          lights: 0..255,
          laser: 0..255,
          tilt: 1000..2000,
          last_ping: non_neg_integer() | nil,
          commands: non_neg_integer(),
          bad_commands: non_neg_integer()
        }

  @doc "Firmware started at `now` (ms). Options: `:wiring`, `:deadman_ms`."
  @spec new(integer(), keyword()) :: t()
  def new(now, opts \\ []) do
    %__MODULE__{
      wiring: Keyword.get(opts, :wiring) || Wiring.default(),
      deadman_ms: Keyword.get(opts, :deadman_ms, 3_000),
      fed_at: now
    }
  end

  @doc """
  Bytes from the server at `now` (ms): returns the firmware and the bytes to send back.

      iex> alias Neptunus.Vehicle.Board.SITL.Firmware
      iex> {fw, out} = Firmware.receive(Firmware.new(0), "go(1250,1500,1750,1);ping(3);", 10)
      iex> {fw.thrusters, out}
      {%{port: 0.5, vertical: 0.0, starboard: 0.5}, "pong:3;\\n"}
  """
  @spec receive(t(), binary(), integer()) :: {t(), binary()}
  def receive(%__MODULE__{} = fw, bytes, now) do
    {commands, rest} = OpenROV.split_commands(fw.pending <> bytes)
    # a babbling line without ';' must not grow without bound
    rest = if byte_size(rest) > @max_pending, do: "", else: rest

    {fw, out} =
      Enum.reduce(commands, {%{fw | pending: rest}, []}, fn text, {fw, out} ->
        case OpenROV.parse_command(text) do
          {:ok, command} ->
            {fw, reply} = command(%{fw | commands: fw.commands + 1}, command, now)
            {fw, [reply | out]}

          {:error, _} ->
            {%{fw | bad_commands: fw.bad_commands + 1}, out}
        end
      end)

    {fw, out |> Enum.reverse() |> IO.iodata_to_binary()}
  end

  defp command(%{tripped: true} = fw, {:go, _, _, _, _}, _now), do: {fw, []}

  defp command(fw, {:go, a, b, c, 1}, _now),
    do: {output(%{fw | target_us: {a, b, c}, ramp_at: nil}, {a, b, c}), []}

  defp command(fw, {:go, a, b, c, 0}, now) do
    ramp_at = if {a, b, c} == fw.out_us, do: nil, else: fw.ramp_at || now
    {%{fw | target_us: {a, b, c}, ramp_at: ramp_at}, []}
  end

  defp command(fw, {:ping, n}, now) do
    fw = %{fw | fed_at: now, last_ping: n}
    recovered = if fw.tripped, do: "deadman:0;\n", else: []
    {%{fw | tripped: false}, [recovered, "pong:#{n};\n"]}
  end

  defp command(fw, :stop, _now), do: {neutral(fw), []}
  defp command(fw, {:ligt, n}, _now), do: {%{fw | lights: n}, []}
  defp command(fw, {:claser, n}, _now), do: {%{fw | laser: n}, []}
  defp command(fw, {:tilt, us}, _now), do: {%{fw | tilt: us}, []}
  # motor modifiers (sent by the board link at every open): not modelled here
  defp command(fw, {mtrmod, _, _, _}, _now) when mtrmod in [:mtrmod1, :mtrmod2], do: {fw, []}

  @doc """
  The deadman check at `now` (ms): returns the firmware and bytes to send (`deadman:1;` when it
  trips).

      iex> alias Neptunus.Vehicle.Board.SITL.Firmware
      iex> {fw, _} = Firmware.receive(Firmware.new(0, deadman_ms: 100), "go(2000,2000,2000,1);", 0)
      iex> {fw, out} = Firmware.tick(fw, 101)
      iex> {fw.thrusters, fw.tripped, out}
      {%{port: 0.0, vertical: 0.0, starboard: 0.0}, true, "deadman:1;\\n"}
  """
  @spec tick(t(), integer()) :: {t(), binary()}
  def tick(%__MODULE__{tripped: false} = fw, now) do
    if now - fw.fed_at > fw.deadman_ms,
      do: {%{neutral(fw) | tripped: true}, "deadman:1;\n"},
      else: {ramp(fw, now), ""}
  end

  def tick(fw, _now), do: {fw, ""}

  defp neutral(fw), do: output(%{fw | target_us: @neutral_us, ramp_at: nil}, @neutral_us)

  defp output(fw, us), do: %{fw | out_us: us, thrusters: Wiring.from_us(fw.wiring, us)}

  # the ramp steps due by `now`
  defp ramp(%__MODULE__{ramp_at: nil} = fw, _now), do: fw
  defp ramp(%__MODULE__{ramp_at: at} = fw, now) when now < at, do: fw

  defp ramp(%__MODULE__{ramp_at: at, out_us: {p, v, s}, target_us: {tp, tv, ts}} = fw, now) do
    out = {ramp_step(p, tp), ramp_step(v, tv), ramp_step(s, ts)}
    fw = output(fw, out)

    if out == fw.target_us,
      do: %{fw | ramp_at: nil},
      else: ramp(%{fw | ramp_at: at + @ramp_ms}, now)
  end

  @doc """
  One ramp step of a motor from `current` towards `target` (µs), as the firmware's
  `smoothAdjustedServoPosition` (without its dead-zone skip).

      iex> alias Neptunus.Vehicle.Board.SITL.Firmware
      iex> {Firmware.ramp_step(1500, 2000), Firmware.ramp_step(1900, 1600), Firmware.ramp_step(1700, 1200)}
      {1540, 1600, 1500}
  """
  @spec ramp_step(integer(), integer()) :: integer()
  def ramp_step(current, target) do
    cond do
      (current < 1500 and 1500 < target) or (target < 1500 and 1500 < current) -> 1500
      abs(1500 - target) < abs(1500 - current) -> target
      target > current -> current + min(target - current, @ramp_us)
      true -> current - min(current - target, @ramp_us)
    end
  end

  @doc "The navigation-data line for a board sample (see `Neptunus.Vehicle.Board.sample/0`)."
  @spec navdata(Neptunus.Vehicle.Board.sample(), t()) :: binary()
  def navdata(%{measurement: m}, %__MODULE__{thrusters: thr}) do
    yaw = if m.heading >= :math.pi(), do: m.heading - 2 * :math.pi(), else: m.heading

    OpenROV.format_line(
      [
        heading: m.heading,
        depth: m.depth,
        pitch: m.pitch,
        roll: m.roll,
        yaw: yaw,
        forward_thrust: (thr.port + thr.starboard) / 2
      ],
      3
    ) <> "\n"
  end

  @doc "The board-status line (voltage, current, uptime, pressure, water temperature)."
  @spec shared_data(Neptunus.Vehicle.Board.sample(), t()) :: binary()
  def shared_data(%{t: t, measurement: m}, %__MODULE__{}) do
    OpenROV.format_line(
      [
        voltage: m.voltage,
        current: m.current,
        board_time: t,
        pressure: (@surface_mbar + @mbar_per_m * m.depth) * 100,
        temperature: @water_temp
      ],
      3
    ) <> "\n"
  end
end
