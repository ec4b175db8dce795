defmodule Neptunus.Vehicle.Board.OpenROV.BoardLink do
  @moduledoc """
  What the board's replies say about the link to an OpenROV board, as a pure value: the board
  link (`Neptunus.Vehicle.Board.OpenROV.UART`) tells it what it sent and what the board said
  (`Neptunus.Vehicle.Board.OpenROV.Readings` events), and it decides when the board's state must be
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
  The firmware also says when it starts: it prints `boot:1;` at the end of its setup (2.5.x
  and 30.x alike), the one sure sign of a reset that follows the opening of the line (its
  millis then have no earlier life on this link to go back from): event `:boot`, a board
  reset too. The millis come from two sources that are not sampled alike: a `pong` carries them as the
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

  ## The board's settings, confirmed

  Every command the board accepts is echoed (`cmd:name(args);`): `confirmed` counts them
  against `sent` (a statistic: a lost `go()` is made good by the next one).

  The settings are not left to chance: the motor modifiers (`mtrmod1`, `mtrmod2`, from the
  wiring, given to `new/2`), the lights, the laser and the tilt (`set/4`) are each *pending*
  until the board echoes that very command — name and arguments as written
  (`OpenROV.Protocol.call/1`). A pending setting is written again every `retry_ms` (250); after
  `attempts` (8) writes it is *failed*, with a reason, and still written every `slow_retry_ms`
  (1000) until the board confirms it. A board that restarts has lost them all: every (re)open, board
  reset and deadman recovery makes them pending again and writes them, after a neutral `go()`
  (actions `:neutral` and `{:send, key, command}`, in that order). `{:settings, summary}` says when
  the summary (`settings/1`: `:confirmed`, `:pending` or `:failed`, what is not confirmed, why)
  changes. The shell runs `tick/2` at `next_tick_at/1`.

  ## Thrust held until the motors are set

  Until both motor modifiers are confirmed the board's motors may be unbalanced (the firmware
  defaults to reverse ×2), so a thrust demand other than neutral is *held* (`demand/2`
  answers `:hold`: the shell writes a neutral `go()` instead), action `{:hold, reason}` when a
  hold begins. When the modifiers are confirmed, action `:release`: the shell writes the
  demand it holds (the latest; a neutral demand ends the hold). A demand standing when the
  board resets is held the same way, so a board reset mid-dive stops the vehicle until the
  settings are confirmed again, and then it goes on. A new link (`opened/2`) and a deadman
  recovery start neutral instead: a demand from before them is not resumed, the next one is
  (the board link's rule: the next link starts neutral). A hold cannot last silently: the
  settings' summary and `thrust_held` are in the link status, and a failed setting has its
  reason.
  """

  alias Neptunus.Vehicle.Board.OpenROV

  @armed_after_ms 180_000
  @deadman_timeout_ms 2_000
  @max_outstanding 16
  @wrap 4_294_967_296
  # the order settings are written in after a restart: the motor modifiers first
  @setting_keys [:mtrmod1, :mtrmod2, :lights, :laser, :tilt]
  @motor_keys [:mtrmod1, :mtrmod2]

  @enforce_keys [:profile]
  defstruct [
    :profile,
    detected: nil,
    mismatch_reported: false,
    up: false,
    outstanding: [],
    rtt_ms: nil,
    pong_at_ms: nil,
    board_ms: nil,
    board_ms_at: nil,
    clocks: %{},
    pong_ms: nil,
    tripped: nil,
    settings: %{},
    demanding: false,
    held: false,
    retry_ms: 250,
    attempts: 8,
    slow_retry_ms: 1_000,
    sent: 0,
    confirmed: 0,
    crc_failures: 0,
    resets: 0,
    deadman_recoveries: 0
  ]

  @typedoc "A board setting: the motor modifiers, lights, laser, tilt."
  @type setting_key :: :mtrmod1 | :mtrmod2 | :lights | :laser | :tilt

  @typedoc """
  One setting: the `command` that sets it (unframed), the `echo` that confirms it (name and
  arguments, `OpenROV.Protocol.call/1`), its `state`; `sends` — writes since it became pending,
  `first_sent_at`/`sent_at` — the first and the last of them (our clock), nil before any;
  `reason` — why it failed.
  """
  @type setting :: %{
          command: binary(),
          echo: {String.t(), [String.t()]},
          state: :pending | :confirmed | :failed,
          sends: non_neg_integer(),
          first_sent_at: integer() | nil,
          sent_at: integer() | nil,
          reason: String.t() | nil
        }

  @typedoc """
  What the settings look like (`settings/1`): all `:confirmed`, some `:pending`, or some
  `:failed` (past the bound of writes, with the `reason` of the first); `pending` names what
  is not confirmed, in writing order.
  """
  @type summary :: %{
          state: :confirmed | :pending | :failed,
          pending: [setting_key()],
          reason: String.t() | nil
        }

  @typedoc """
  * `profile` — the configured firmware line; `detected` — what the board's output says
  * `up` — the link is open (`opened/2` … `closed/1`)
  * `outstanding` — `{n, sent_at}` of the pings not answered yet, oldest first
  * `rtt_ms` — the last round trip; `pong_at_ms` — when the last pong arrived (our clock)
  * `board_ms`, `board_ms_at` — the board's latest millis and when we saw them
  * `clocks` — the board's last millis from each source (`:pong`, `:time`) in its current life
  * `pong_ms` — the board's millis in its last pong
  * `tripped` — why the board's deadman is believed tripped, nil when it is not
  * `settings` — the board's settings (see the moduledoc)
  * `demanding` — the latest thrust demand is not neutral; `held` — and it is held
  * `retry_ms`, `attempts`, `slow_retry_ms` — how settings are written again (moduledoc)
  * counters: `sent`, `confirmed`, `crc_failures`, `resets`, `deadman_recoveries`
  """
  @type t :: %__MODULE__{
          profile: OpenROV.Protocol.profile(),
          detected: OpenROV.Protocol.profile() | nil,
          mismatch_reported: boolean(),
          up: boolean(),
          outstanding: [{non_neg_integer(), integer()}],
          rtt_ms: integer() | nil,
          pong_at_ms: integer() | nil,
          board_ms: non_neg_integer() | nil,
          board_ms_at: integer() | nil,
          clocks: %{optional(:pong | :time) => non_neg_integer()},
          pong_ms: non_neg_integer() | nil,
          tripped: String.t() | nil,
          settings: %{optional(setting_key()) => setting()},
          demanding: boolean(),
          held: boolean(),
          retry_ms: pos_integer(),
          attempts: pos_integer(),
          slow_retry_ms: pos_integer(),
          sent: non_neg_integer(),
          confirmed: non_neg_integer(),
          crc_failures: non_neg_integer(),
          resets: non_neg_integer(),
          deadman_recoveries: non_neg_integer()
        }

  @typedoc """
  What the shell does, in order: log and tell the vehicle (`:board_reset`,
  `:deadman_recovery`, `:firmware_mismatch`, `:hold`, `:settings`), write a neutral `go()`
  (`:neutral`), write a setting's command (`:send`), write the held demand (`:release`).
  """
  @type action ::
          {:board_reset, String.t()}
          | {:deadman_recovery, String.t()}
          | {:firmware_mismatch, OpenROV.Protocol.profile()}
          | :neutral
          | {:send, setting_key(), binary()}
          | {:settings, summary()}
          | {:hold, String.t()}
          | :release

  @doc """
  A link to a board configured with firmware `profile`. Options: `:settings` — the settings
  the board must have from the start, `[{key, command}]` (the motor modifiers from the
  wiring); `:retry_ms` (250), `:attempts` (8), `:slow_retry_ms` (1000) — see the moduledoc.
  """
  @spec new(OpenROV.Protocol.profile(), keyword()) :: t()
  def new(profile, opts \\ []) when profile in [:openrov_25, :openrov_30] do
    l = %__MODULE__{
      profile: profile,
      retry_ms: Keyword.get(opts, :retry_ms, 250),
      attempts: Keyword.get(opts, :attempts, 8),
      slow_retry_ms: Keyword.get(opts, :slow_retry_ms, 1_000)
    }

    opts
    |> Keyword.get(:settings, [])
    |> Enum.reduce(l, fn {key, command}, l -> put_setting(l, key, command) end)
  end

  @doc """
  A new link session (the port was (re)opened) at `now`: what was learnt about the board's
  clock, pings and deadman is forgotten (counters and the detected firmware line are kept),
  and the board gets neutral and every setting (see the moduledoc).
  """
  @spec opened(t(), integer()) :: {t(), [action()]}
  def opened(%__MODULE__{} = l, now) do
    # a new link starts neutral: no demand from before it is resumed
    l = %{
      l
      | up: true,
        demanding: false,
        held: false,
        outstanding: [],
        rtt_ms: nil,
        pong_at_ms: nil,
        board_ms: nil,
        board_ms_at: nil,
        clocks: %{},
        pong_ms: nil,
        tripped: nil
    }

    restart(l, now, [])
  end

  @doc "The link went down: nothing is written, nothing is held, until it opens again."
  @spec closed(t()) :: t()
  def closed(%__MODULE__{} = l), do: %{l | up: false, held: false}

  @doc "A command was written (`ping` is one too; see `ping_sent/3`)."
  @spec sent(t()) :: t()
  def sent(%__MODULE__{} = l), do: %{l | sent: l.sent + 1}

  @doc "Ping `n` was written at `now` (ms)."
  @spec ping_sent(t(), non_neg_integer(), integer()) :: t()
  def ping_sent(%__MODULE__{} = l, n, now),
    do: %{l | outstanding: Enum.take(l.outstanding ++ [{n, now}], -@max_outstanding)}

  @doc """
  An event from the board (see `Neptunus.Vehicle.Board.OpenROV.Readings`) seen at `now` (ms): the
  link and the actions it calls for, in order.
  """
  @spec event(t(), Neptunus.Vehicle.Board.OpenROV.Readings.event(), integer()) ::
          {t(), [action()]}
  def event(%__MODULE__{} = l, :rawcmd, _now), do: detected(l, :openrov_30)

  def event(%__MODULE__{} = l, {:crc, :pass}, _now), do: detected(l, :openrov_30)

  def event(%__MODULE__{} = l, {:crc, {:fail, _, _}}, _now),
    do: detected(%{l | crc_failures: l.crc_failures + 1}, :openrov_30)

  def event(%__MODULE__{} = l, {:echo, name, args, with_crc?}, _now) do
    l = %{l | confirmed: l.confirmed + 1}
    {l, actions} = if with_crc?, do: detected(l, :openrov_30), else: detected(l, :openrov_25)
    {l, more} = confirm(l, name, args)
    {l, actions ++ more}
  end

  # the firmware printed its start-up line: a new life
  def event(%__MODULE__{} = l, :boot, now) do
    reason = "board restarted (it printed boot:1)"
    l = %{l | board_ms: 0, board_ms_at: now}
    new_life(l, now, {:board_reset, reason})
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

    {l, deadman_actions} = pong_deadman(l, pong.millis, reset_actions != [], now)
    {l, reset_actions ++ deadman_actions}
  end

  defp pong_deadman(l, millis, reset?, now) do
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
        # the board stopped on its own: it starts neutral, as a new link does
        l = %{
          l
          | tripped: nil,
            deadman_recoveries: l.deadman_recoveries + 1,
            demanding: false,
            held: false
        }

        restart(l, now, [{:deadman_recovery, reason}])
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
      {l, actions} = new_life(l, now, {:board_reset, reason})
      {%{l | clocks: %{source => ms}}, actions}
    else
      {%{l | clocks: Map.put(l.clocks, source, ms)}, []}
    end
  end

  # A restarted board: its deadman is disarmed, its earlier readings and pongs are of another
  # life, and it has lost its settings.
  defp new_life(l, now, reset) do
    l = %{l | resets: l.resets + 1, tripped: nil, pong_ms: nil, clocks: %{}}
    restart(l, now, [reset])
  end

  defp wrapped?(before, now), do: before > @wrap - 600_000 and now < 600_000

  defp seconds(ms), do: Float.round(ms / 1000, 1)

  defp detected(%__MODULE__{} = l, line) do
    l = %{l | detected: line}

    if line != l.profile and not l.mismatch_reported,
      do: {%{l | mismatch_reported: true}, [{:firmware_mismatch, line}]},
      else: {l, []}
  end

  # Settings -----------------------------------------------------------------------------

  @doc """
  The board must have setting `key` as `command` (unframed, e.g. `"ligt(80);"`): while the
  link is up it is written now (`{:send, key, command}`) and is pending until the board
  echoes it (a command it already confirmed is written again and stays confirmed); while
  down it is kept for the next open.
  """
  @spec set(t(), setting_key(), binary(), integer()) :: {t(), [action()]}
  def set(%__MODULE__{} = l, key, command, now) when key in @setting_keys do
    before = settings(l)

    case Map.get(l.settings, key) do
      %{command: ^command, state: :confirmed} when l.up ->
        {l, [{:send, key, command}]}

      _ ->
        l = put_setting(l, key, command)

        if l.up do
          l = update_in(l.settings[key], &written(&1, now))
          {l, [{:send, key, command} | summary_changed(before, l)]}
        else
          {l, []}
        end
    end
  end

  defp put_setting(l, key, command) when key in @setting_keys do
    setting = %{
      command: command,
      echo: OpenROV.Protocol.call(command),
      state: :pending,
      sends: 0,
      first_sent_at: nil,
      sent_at: nil,
      reason: nil
    }

    %{l | settings: Map.put(l.settings, key, setting)}
  end

  defp written(setting, now),
    do: %{
      setting
      | sends: setting.sends + 1,
        sent_at: now,
        first_sent_at: setting.first_sent_at || now
    }

  # The board (re)started, or the link opened: neutral first, then every setting, pending; a
  # standing demand is held until the motor modifiers are confirmed again.
  defp restart(l, now, lead) do
    before = settings(l)

    settings =
      Map.new(l.settings, fn {key, setting} ->
        {key,
         written(%{setting | state: :pending, sends: 0, first_sent_at: nil, reason: nil}, now)}
      end)

    l = %{l | settings: settings}
    sends = for key <- @setting_keys, s = settings[key], do: {:send, key, s.command}
    {l, hold} = hold(l)
    {l, lead ++ [:neutral | sends] ++ summary_changed(before, l) ++ hold}
  end

  # An echo: the setting whose command it is, is confirmed.
  defp confirm(l, _name, nil), do: {l, []}

  defp confirm(l, name, args) do
    echo = {name, args}

    case Enum.find(l.settings, fn {_k, s} -> s.echo == echo and s.state != :confirmed end) do
      nil ->
        {l, []}

      {key, _} ->
        before = settings(l)
        l = update_in(l.settings[key], &%{&1 | state: :confirmed, reason: nil})
        {l, release} = release(l)
        {l, summary_changed(before, l) ++ release}
    end
  end

  @doc """
  Writes again what the board has not confirmed (see the moduledoc): due at `now`, pending
  settings are written (`{:send, key, command}`); a pending setting written `attempts` times
  fails, with a reason (`{:settings, summary}`), and is written every `slow_retry_ms` on.
  """
  @spec tick(t(), integer()) :: {t(), [action()]}
  def tick(%__MODULE__{up: false} = l, _now), do: {l, []}

  def tick(%__MODULE__{} = l, now) do
    before = settings(l)

    {l, sends} =
      Enum.reduce(@setting_keys, {l, []}, fn key, {l, sends} ->
        case l.settings[key] do
          %{state: state, sent_at: at} = s when state != :confirmed and at != nil ->
            if now - at >= interval(l, s) do
              s = if state == :pending and s.sends >= l.attempts, do: fail(s, now), else: s
              l = %{l | settings: Map.put(l.settings, key, written(s, now))}
              {l, [{:send, key, s.command} | sends]}
            else
              {l, sends}
            end

          _ ->
            {l, sends}
        end
      end)

    {l, Enum.reverse(sends) ++ summary_changed(before, l)}
  end

  defp interval(l, %{state: :failed}), do: l.slow_retry_ms
  defp interval(l, _setting), do: l.retry_ms

  defp fail(s, now) do
    reason =
      "the board has not confirmed #{s.command} (no echo after #{s.sends} writes in " <>
        "#{seconds(now - s.first_sent_at)} s: is its firmware line configured right, and " <>
        "is the line sound?)"

    %{s | state: :failed, reason: reason}
  end

  @doc "When `tick/2` has something to do next, nil when every setting is confirmed (or the link is down)."
  @spec next_tick_at(t()) :: integer() | nil
  def next_tick_at(%__MODULE__{up: false}), do: nil

  def next_tick_at(%__MODULE__{} = l) do
    l.settings
    |> Map.values()
    |> Enum.filter(&(&1.state != :confirmed and &1.sent_at != nil))
    |> Enum.map(&(&1.sent_at + interval(l, &1)))
    |> Enum.min(fn -> nil end)
  end

  @doc """
  The settings' summary (see `t:summary/0`).

      iex> alias Neptunus.Vehicle.Board.OpenROV.BoardLink
      iex> l = BoardLink.new(:openrov_25, settings: [mtrmod1: "mtrmod1(100,100,100);"])
      iex> BoardLink.settings(l)
      %{state: :pending, pending: [:mtrmod1], reason: nil}
  """
  @spec settings(t()) :: summary()
  def settings(%__MODULE__{settings: settings}) do
    open = for key <- @setting_keys, s = settings[key], s.state != :confirmed, do: {key, s}

    case Enum.find(open, fn {_key, s} -> s.state == :failed end) do
      {_key, failed} -> %{state: :failed, pending: Keyword.keys(open), reason: failed.reason}
      nil when open == [] -> %{state: :confirmed, pending: [], reason: nil}
      nil -> %{state: :pending, pending: Keyword.keys(open), reason: nil}
    end
  end

  defp summary_changed(before, l) do
    case settings(l) do
      ^before -> []
      now -> [{:settings, now}]
    end
  end

  @doc """
  Whether the board has confirmed the motor modifiers it must have (in its current life): a
  link given none has nothing to wait for.
  """
  @spec motors_confirmed?(t()) :: boolean()
  def motors_confirmed?(%__MODULE__{settings: settings}) do
    Enum.all?(@motor_keys, fn key ->
      case settings do
        %{^key => %{state: state}} -> state == :confirmed
        _ -> true
      end
    end)
  end

  # Thrust ---------------------------------------------------------------------------------

  @doc """
  A thrust demand (`neutral?`: all three motors at neutral). `:send` — write it; `:hold` —
  write a neutral `go()` instead: the board has not confirmed its motor modifiers, and the
  demand goes out with action `:release` once it has (see the moduledoc). On the control
  path: a couple of map lookups.
  """
  @spec demand(t(), boolean()) :: {t(), :send | :hold, [action()]}
  def demand(%__MODULE__{} = l, true), do: {%{l | demanding: false, held: false}, :send, []}

  def demand(%__MODULE__{} = l, false) do
    l = %{l | demanding: true}

    if motors_confirmed?(l) do
      {l, :send, []}
    else
      {l, actions} = hold(l)
      {l, :hold, actions}
    end
  end

  defp hold(%__MODULE__{up: true, demanding: true, held: false} = l) do
    if motors_confirmed?(l) do
      {l, []}
    else
      {%{l | held: true}, [{:hold, hold_reason(l)}]}
    end
  end

  defp hold(l), do: {l, []}

  defp hold_reason(l) do
    pending = l |> settings() |> Map.fetch!(:pending) |> Enum.filter(&(&1 in @motor_keys))

    "board settings not confirmed (#{Enum.join(pending, ", ")}): thrust held at neutral " <>
      "until the board confirms them"
  end

  defp release(%__MODULE__{held: true} = l) do
    if motors_confirmed?(l), do: {%{l | held: false}, [:release]}, else: {l, []}
  end

  defp release(l), do: {l, []}

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
    |> Map.merge(settings_status(l))
  end

  @doc """
  The settings' fields of the link status: `board_settings` (`"confirmed"`, `"pending"`,
  `"failed"`), `board_settings_pending` (the names not confirmed), `board_settings_reason`
  (why one failed, else nil) and `thrust_held`.
  """
  @spec settings_status(t()) :: map()
  def settings_status(%__MODULE__{} = l) do
    summary = settings(l)

    %{
      board_settings: Atom.to_string(summary.state),
      board_settings_pending: Enum.map(summary.pending, &Atom.to_string/1),
      board_settings_reason: summary.reason,
      thrust_held: l.held
    }
  end

  @doc """
  The configuration name of a profile.

      iex> Neptunus.Vehicle.Board.OpenROV.BoardLink.profile_name(:openrov_30)
      "openrov-30"
  """
  @spec profile_name(OpenROV.Protocol.profile()) :: String.t()
  def profile_name(:openrov_25), do: "openrov-2.5"
  def profile_name(:openrov_30), do: "openrov-30"

  @doc """
  The profile of a configuration name.

      iex> Neptunus.Vehicle.Board.OpenROV.BoardLink.parse_profile("openrov-2.5")
      {:ok, :openrov_25}
      iex> Neptunus.Vehicle.Board.OpenROV.BoardLink.parse_profile("openrov-3")
      {:error, "openrov-2.5 or openrov-30, not \\"openrov-3\\""}
  """
  @spec parse_profile(String.t()) :: {:ok, OpenROV.Protocol.profile()} | {:error, String.t()}
  def parse_profile("openrov-2.5"), do: {:ok, :openrov_25}
  def parse_profile("openrov-30"), do: {:ok, :openrov_30}
  def parse_profile(other), do: {:error, "openrov-2.5 or openrov-30, not #{inspect(other)}"}
end
