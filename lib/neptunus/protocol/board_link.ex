defmodule Neptunus.Protocol.BoardLink do
  @moduledoc """
  What the board's replies say about the link to an OpenROV board, as a pure value: the board
  link (`Neptunus.Vehicle.Board.UART`) tells it what it sent and what the board said
  (`Neptunus.Vehicle.Board.Readings` events), and it decides when the board's state must be
  sent again and what the link status shows.

  ## Ping, liveness, round trip

  The firmware answers `ping(n);` with `pong:<argument count>,<millis>;` (its uptime in ms).
  Pongs are matched to pings in order: the round-trip time is from the oldest unanswered ping
  being written to its pong arriving. The pong's age is the link's liveness.

  ## Board reset

  The board's millis never go backwards while it runs; when they do, the board has restarted
  (a USB Arduino resets when its port is opened; a brown-out resets it too). A restarted
  board has forgotten the motor modifiers, lights, laser and tilt: action
  `{:board_reset, reason}`. (A wrap of the 32-bit millis after 49.7 days is not a reset.)
  The millis come from two sources that are not sampled alike: a `pong` carries them as the
  ping arrives, the `time` field the value the firmware took at its last navigation tick
  (every ~101 ms, later still when its loop runs late), so a `time` printed just after a
  `pong` can be behind it while the board runs on. So a `time` is compared only with the
  previous `time`, and a `pong` (the freshest reading) with every earlier reading of the
  board's current life; a reset starts a new life for both.

  ## The board's deadman

  The firmware's deadman arms only once its uptime passes 180 s; armed, it trips when no ping
  has arrived for 2 s: it turns depth and heading hold off and stops the motors (the 30.x
  firmware prints these as `icmd:deptloff();`, `icmd:headloff();`, `icmd:stop();`), then
  blinks the lights (`icmd:ligt(50);` / `icmd:ligt(0);` every 500 ms) until the next ping,
  which restarts it (`start`) and leaves the lights where the blink left them. So a trip is
  detected from `icmd:stop(` / `icmd:ligt(` lines, or from two consecutive pongs more than
  2 s apart on the board's clock with the later one past 180 s (the 2.5 firmware prints no
  internal commands). It is cleared by the next pong: action `{:deadman_recovery, reason}`.

  ## Firmware line

  The 30.x firmware prints `rawcmd:` and `crc:` for every command it receives (and
  `crc:fail` for a command without a valid CRC byte); the 2.5 firmware never does, and
  echoes a command as `cmd:…;` on a line of its own (30.x prints `crc:pass;` before the echo,
  on the same line); given a CRC-prefixed command, a 2.5 board echoes it with the CRC byte
  before the name (`cmd:<crc>ping(7);`) and does not recognise it. The line so detected is
  kept in `detected`; when it differs from the configured profile, action `{:firmware_mismatch, detected}` once — the profile is never
  switched on a guess.

  ## Confirmed commands

  Every command the board accepts is echoed (`cmd:name(args);`): `confirmed` counts them
  against `sent`.
  """

  alias Neptunus.Protocol.OpenROV

  @armed_after_ms 180_000
  @deadman_timeout_ms 2_000
  @max_outstanding 16
  @wrap 4_294_967_296

  @enforce_keys [:profile]
  defstruct [
    :profile,
    detected: nil,
    mismatch_reported: false,
    outstanding: [],
    rtt_ms: nil,
    pong_at_ms: nil,
    board_ms: nil,
    board_ms_at: nil,
    clocks: %{},
    pong_ms: nil,
    tripped: nil,
    sent: 0,
    confirmed: 0,
    crc_failures: 0,
    resets: 0,
    deadman_recoveries: 0
  ]

  @typedoc """
  * `profile` — the configured firmware line; `detected` — what the board's output says
  * `outstanding` — `{n, sent_at}` of the pings not answered yet, oldest first
  * `rtt_ms` — the last round trip; `pong_at_ms` — when the last pong arrived (our clock)
  * `board_ms`, `board_ms_at` — the board's latest millis and when we saw them
  * `clocks` — the board's last millis from each source (`:pong`, `:time`) in its current life
  * `pong_ms` — the board's millis in its last pong
  * `tripped` — why the board's deadman is believed tripped, nil when it is not
  * counters: `sent`, `confirmed`, `crc_failures`, `resets`, `deadman_recoveries`
  """
  @type t :: %__MODULE__{
          profile: OpenROV.profile(),
          detected: OpenROV.profile() | nil,
          mismatch_reported: boolean(),
          outstanding: [{non_neg_integer(), integer()}],
          rtt_ms: integer() | nil,
          pong_at_ms: integer() | nil,
          board_ms: non_neg_integer() | nil,
          board_ms_at: integer() | nil,
          clocks: %{optional(:pong | :time) => non_neg_integer()},
          pong_ms: non_neg_integer() | nil,
          tripped: String.t() | nil,
          sent: non_neg_integer(),
          confirmed: non_neg_integer(),
          crc_failures: non_neg_integer(),
          resets: non_neg_integer(),
          deadman_recoveries: non_neg_integer()
        }

  @type action ::
          {:board_reset, String.t()}
          | {:deadman_recovery, String.t()}
          | {:firmware_mismatch, OpenROV.profile()}

  @doc "A link to a board configured with firmware `profile`."
  @spec new(OpenROV.profile()) :: t()
  def new(profile) when profile in [:openrov_25, :openrov_30], do: %__MODULE__{profile: profile}

  @doc """
  A new link session (the port was (re)opened): what was learnt about the board's clock,
  pings and deadman is forgotten; counters and the detected firmware line are kept.
  """
  @spec opened(t()) :: t()
  def opened(%__MODULE__{} = l) do
    %{
      l
      | outstanding: [],
        rtt_ms: nil,
        pong_at_ms: nil,
        board_ms: nil,
        board_ms_at: nil,
        clocks: %{},
        pong_ms: nil,
        tripped: nil
    }
  end

  @doc "A command was written (`ping` is one too; see `ping_sent/3`)."
  @spec sent(t()) :: t()
  def sent(%__MODULE__{} = l), do: %{l | sent: l.sent + 1}

  @doc "Ping `n` was written at `now` (ms)."
  @spec ping_sent(t(), non_neg_integer(), integer()) :: t()
  def ping_sent(%__MODULE__{} = l, n, now),
    do: %{l | outstanding: Enum.take(l.outstanding ++ [{n, now}], -@max_outstanding)}

  @doc """
  An event from the board (see `Neptunus.Vehicle.Board.Readings`) seen at `now` (ms): the link
  and the actions it calls for, in order.
  """
  @spec event(t(), Neptunus.Vehicle.Board.Readings.event(), integer()) :: {t(), [action()]}
  def event(%__MODULE__{} = l, :rawcmd, _now), do: detected(l, :openrov_30)

  def event(%__MODULE__{} = l, {:crc, :pass}, _now), do: detected(l, :openrov_30)

  def event(%__MODULE__{} = l, {:crc, {:fail, _, _}}, _now),
    do: detected(%{l | crc_failures: l.crc_failures + 1}, :openrov_30)

  def event(%__MODULE__{} = l, {:echo, _name, with_crc?}, _now) do
    l = %{l | confirmed: l.confirmed + 1}
    if with_crc?, do: detected(l, :openrov_30), else: detected(l, :openrov_25)
  end

  # a board without CRC checking echoing our CRC byte as part of the command's name
  def event(%__MODULE__{} = l, {:echo_prefixed, _name}, _now), do: detected(l, :openrov_25)

  def event(%__MODULE__{} = l, {:icmd, name}, _now) when name in ["stop", "ligt"] do
    {%{l | tripped: l.tripped || "the board's deadman tripped (icmd:#{name})"}, []}
  end

  def event(%__MODULE__{} = l, {:icmd, _name}, _now), do: {l, []}

  def event(%__MODULE__{} = l, {:board_time, ms}, now), do: clock(l, :time, ms, now)

  def event(%__MODULE__{} = l, {:pong, pong}, now) do
    l =
      case l.outstanding do
        [{_n, sent_at} | rest] -> %{l | outstanding: rest, rtt_ms: now - sent_at}
        [] -> l
      end

    l = %{l | pong_at_ms: now}

    {l, reset_actions} =
      case pong.millis do
        nil -> {l, []}
        ms -> clock(l, :pong, ms, now)
      end

    {l, deadman_actions} = pong_deadman(l, pong.millis, reset_actions != [])
    {l, reset_actions ++ deadman_actions}
  end

  defp pong_deadman(l, millis, reset?) do
    gap_trip =
      cond do
        reset? or millis == nil or l.pong_ms == nil ->
          nil

        millis - l.pong_ms > @deadman_timeout_ms and millis > @armed_after_ms ->
          "no ping reached the board for #{Float.round((millis - l.pong_ms) / 1000, 1)} s"

        true ->
          nil
      end

    l = if millis, do: %{l | pong_ms: millis}, else: l

    case l.tripped || gap_trip do
      nil ->
        {l, []}

      reason ->
        {%{l | tripped: nil, deadman_recoveries: l.deadman_recoveries + 1},
         [{:deadman_recovery, reason}]}
    end
  end

  defp clock(l, source, ms, now) do
    previous =
      case source do
        :pong -> l.clocks |> Map.values() |> Enum.max(fn -> nil end)
        :time -> Map.get(l.clocks, :time)
      end

    backwards? = previous != nil and ms < previous and not wrapped?(previous, ms)
    was = max(l.board_ms || 0, previous || 0)
    l = %{l | board_ms: ms, board_ms_at: now}

    if backwards? do
      reason = "board restarted (its uptime went from #{seconds(was)} s to #{seconds(ms)} s)"
      # a restarted board's deadman is disarmed, and its earlier readings and pongs are of
      # another life
      {%{l | resets: l.resets + 1, tripped: nil, pong_ms: nil, clocks: %{source => ms}},
       [{:board_reset, reason}]}
    else
      {%{l | clocks: Map.put(l.clocks, source, ms)}, []}
    end
  end

  defp wrapped?(before, now), do: before > @wrap - 600_000 and now < 600_000

  defp seconds(ms), do: Float.round(ms / 1000, 1)

  defp detected(%__MODULE__{} = l, line) do
    l = %{l | detected: line}

    if line != l.profile and not l.mismatch_reported,
      do: {%{l | mismatch_reported: true}, [{:firmware_mismatch, line}]},
      else: {l, []}
  end

  @doc """
  The board's uptime at `now` (ms) extrapolated from the last millis it reported, nil if it
  has reported none on this link.
  """
  @spec board_uptime_ms(t(), integer()) :: non_neg_integer() | nil
  def board_uptime_ms(%__MODULE__{board_ms: nil}, _now), do: nil
  def board_uptime_ms(%__MODULE__{} = l, now), do: l.board_ms + (now - l.board_ms_at)

  @doc """
  Whether the board's own deadman is armed (its uptime past 180 s): nil when not known. While
  it is not, only the server's deadman protects the vehicle.
  """
  @spec board_deadman_armed?(t(), integer()) :: boolean() | nil
  def board_deadman_armed?(%__MODULE__{} = l, now) do
    case board_uptime_ms(l, now) do
      nil -> nil
      ms -> ms > @armed_after_ms
    end
  end

  @doc "The link status fields (see docs/API.md) at `now` (ms)."
  @spec status(t(), integer()) :: map()
  def status(%__MODULE__{} = l, now) do
    %{
      firmware: profile_name(l.profile),
      detected_firmware: l.detected && profile_name(l.detected),
      firmware_mismatch: l.detected != nil and l.detected != l.profile,
      rtt_ms: l.rtt_ms,
      pong_age_ms: l.pong_at_ms && now - l.pong_at_ms,
      board_uptime_ms: board_uptime_ms(l, now),
      board_deadman_armed: board_deadman_armed?(l, now),
      board_deadman_tripped: l.tripped != nil,
      commands_sent: l.sent,
      commands_confirmed: l.confirmed,
      crc_failures: l.crc_failures,
      board_resets: l.resets,
      deadman_recoveries: l.deadman_recoveries
    }
  end

  @doc """
  The configuration name of a profile.

      iex> Neptunus.Protocol.BoardLink.profile_name(:openrov_30)
      "openrov-30"
  """
  @spec profile_name(OpenROV.profile()) :: String.t()
  def profile_name(:openrov_25), do: "openrov-2.5"
  def profile_name(:openrov_30), do: "openrov-30"

  @doc """
  The profile of a configuration name.

      iex> Neptunus.Protocol.BoardLink.parse_profile("openrov-2.5")
      {:ok, :openrov_25}
      iex> Neptunus.Protocol.BoardLink.parse_profile("openrov-3")
      {:error, "openrov-2.5 or openrov-30, not \\"openrov-3\\""}
  """
  @spec parse_profile(String.t()) :: {:ok, OpenROV.profile()} | {:error, String.t()}
  def parse_profile("openrov-2.5"), do: {:ok, :openrov_25}
  def parse_profile("openrov-30"), do: {:ok, :openrov_30}
  def parse_profile(other), do: {:error, "openrov-2.5 or openrov-30, not #{inspect(other)}"}
end
