defmodule NeptunusWeb.Socket.FlowControl do
  @moduledoc """
  A connection's flow control (pure): at which process priority it runs, and which frames
  it may drop for a client that reads too slowly. `NeptunusWeb.Socket` keeps one per
  connection, feeds it the clock and its mailbox length, and carries the answers out:
  sending or dropping a frame, and the effects (`t:effect/0`) of a frame received
  (`frame_received/3`), a grant or loss of control (`control_changed/3`) and a dropped
  frame (`telemetry_dropped/3`): a new process priority, the pilot's telemetry first, a log
  line.

  ## Priority

  A connection runs at `:low`, and at `:high` while it pilots a vehicle (between the helm's
  `control_granted` and `control_lost` for that topic, `piloting/3`), like the vehicle's
  control path it commands (see `Neptunus.Vehicle.Helm`). `:normal` would not do for the
  pilot: the BEAM runs `:normal` and `:low` processes from one queue, interleaved, so a
  pilot at `:normal` would wait behind every observer connection that a telemetry broadcast
  made runnable. `:high` runs before both.

  The pilot keeps `:high` only within a frame budget: a client that sends more than
  `pilot_frames_per_s` frames within one second runs at `:normal` for the rest of that
  second (`frame/2`), so a broken or hostile pilot client cannot starve the observers, the
  telemetry or the main station's takeover. The official client sends well under the
  default of 200: thrust at the gamepad's rate, a helm heartbeat every 100 ms, a socket
  heartbeat every 30 s. Frames of a connection that pilots nothing are not counted.

  ## Shedding

  A client that reads slower than its telemetry arrives (a weak link, a busy tablet) makes
  messages wait in its connection's mailbox. Once `backlog` or more wait, `telemetry` frames
  are dropped (`deliver?/3`): the newest ones, at the back of the queue, still go out, so
  the client sees fresh data instead of ever older data. Every other event (`helm`,
  `presence_diff`, `stopped`, replies, …) is always sent. `dropped/2` counts the drops and
  says when to log them: at the first drop, then at most once a minute, with the count.

      iex> alias NeptunusWeb.Socket.FlowControl
      iex> flow = FlowControl.new(pilot_frames_per_s: 2, backlog: 8)
      iex> FlowControl.priority(flow)
      :low
      iex> flow = FlowControl.piloting(flow, "vehicle:a", true)
      iex> FlowControl.priority(flow)
      :high
      iex> {flow, :within} = FlowControl.frame(flow, 0)
      iex> {flow, :within} = FlowControl.frame(flow, 10)
      iex> {flow, :over_budget} = FlowControl.frame(flow, 20)
      iex> FlowControl.priority(flow)
      :normal
      iex> {flow, :within} = FlowControl.frame(flow, 1_000)
      iex> FlowControl.priority(flow)
      :high
  """

  @window_ms 1_000
  @report_every_ms 60_000

  @typedoc """
  * `frame_limit` — frames per second a pilot may send and keep `:high`
  * `backlog` — waiting messages from which on telemetry is dropped
  * `piloting` — the topics this connection pilots
  * `window_start_ms`, `frames` — the current one-second window of the frame budget (ms on a
    monotonic clock) and the frames counted in it
  * `over_budget` — the pilot has sent more than `frame_limit` frames in this window
  * `dropped` — telemetry frames dropped since the last report
  * `reported_at_ms` — when drops were last reported (ms), `nil` before the first drop
  """
  @type t :: %__MODULE__{
          frame_limit: pos_integer(),
          backlog: pos_integer(),
          piloting: MapSet.t(String.t()),
          window_start_ms: integer() | nil,
          frames: non_neg_integer(),
          over_budget: boolean(),
          dropped: non_neg_integer(),
          reported_at_ms: integer() | nil
        }
  @enforce_keys [:frame_limit, :backlog]
  defstruct [
    :frame_limit,
    :backlog,
    :window_start_ms,
    :reported_at_ms,
    piloting: MapSet.new(),
    frames: 0,
    over_budget: false,
    dropped: 0
  ]

  @typedoc "When to log dropped telemetry: the count, and ms since the last report (nil: first)."
  @type report :: {:report, pos_integer(), non_neg_integer() | nil}

  @typedoc """
  What the connection carries out, in order: set its process priority; have the PubSub serve
  it first on a topic (`Neptunus.PubSub.prioritize/2`) or not; log a line.
  """
  @type effect ::
          {:priority, :low | :normal | :high}
          | {:prioritize, String.t(), boolean()}
          | {:log, :info | :warning, String.t()}

  @doc """
  Flow control for a new connection (not piloting): `pilot_frames_per_s` (the frame budget)
  and `backlog` (waiting messages from which on telemetry is dropped), positive integers.
  """
  @spec new(keyword()) :: t()
  def new(opts) when is_list(opts) do
    %__MODULE__{
      frame_limit: positive!(opts, :pilot_frames_per_s),
      backlog: positive!(opts, :backlog)
    }
  end

  defp positive!(opts, key) do
    case Keyword.fetch(opts, key) do
      {:ok, value} when is_integer(value) and value > 0 ->
        value

      {:ok, value} ->
        raise ArgumentError, "#{key} must be a positive integer, got #{inspect(value)}"

      :error ->
        raise ArgumentError, "#{key} is required"
    end
  end

  @doc "The process priority the connection should run at now."
  @spec priority(t()) :: :low | :normal | :high
  def priority(%__MODULE__{} = flow) do
    cond do
      MapSet.size(flow.piloting) == 0 -> :low
      flow.over_budget -> :normal
      true -> :high
    end
  end

  @doc """
  The helm granted (`true`) or took back (`false`) control of `topic`'s vehicle. A
  connection that pilots nothing any more is within budget again.
  """
  @spec piloting(t(), String.t(), boolean()) :: t()
  def piloting(%__MODULE__{} = flow, topic, piloting?)
      when is_binary(topic) and is_boolean(piloting?) do
    piloting =
      if piloting?,
        do: MapSet.put(flow.piloting, topic),
        else: MapSet.delete(flow.piloting, topic)

    %{flow | piloting: piloting, over_budget: flow.over_budget and MapSet.size(piloting) > 0}
  end

  @doc """
  Counts a frame from the client received at `now_ms` (a monotonic clock in ms), while the
  connection pilots. `:within` while the frames of the current one-second window are at
  most the limit; `:over_budget` for the frame that exceeds it (log it: the connection
  drops to `:normal`), `:over` for the later ones. A clock that goes back starts a new
  window.
  """
  @spec frame(t(), integer()) :: {t(), :within | :over_budget | :over}
  def frame(%__MODULE__{} = flow, now_ms) when is_integer(now_ms) do
    if MapSet.size(flow.piloting) == 0 do
      {flow, :within}
    else
      start = flow.window_start_ms

      flow =
        if start == nil or now_ms - start >= @window_ms or now_ms < start,
          do: %{flow | window_start_ms: now_ms, frames: 1},
          else: %{flow | frames: flow.frames + 1}

      over? = flow.frames > flow.frame_limit

      verdict =
        cond do
          not over? -> :within
          flow.over_budget -> :over
          true -> :over_budget
        end

      {%{flow | over_budget: over?}, verdict}
    end
  end

  @doc """
  Whether a broadcast frame of `event` goes out while `waiting` messages wait for the
  connection: always, except `telemetry` once `backlog` or more wait.
  """
  @spec deliver?(t(), String.t(), non_neg_integer()) :: boolean()
  def deliver?(%__MODULE__{backlog: backlog}, event, waiting)
      when is_integer(waiting) and waiting >= 0,
      do: event != "telemetry" or waiting < backlog

  @doc """
  Counts a telemetry frame dropped at `now_ms`. `{:report, count, since_ms}` when the drops
  are to be logged now (the first drop, then at most once a minute; `since_ms` is the time
  since the last report, `nil` at the first), `nil` otherwise.
  """
  @spec dropped(t(), integer()) :: {t(), report() | nil}
  def dropped(%__MODULE__{dropped: dropped, reported_at_ms: reported} = flow, now_ms)
      when is_integer(now_ms) do
    cond do
      reported == nil ->
        {%{flow | dropped: 0, reported_at_ms: now_ms}, {:report, dropped + 1, nil}}

      now_ms - reported >= @report_every_ms ->
        {%{flow | dropped: 0, reported_at_ms: now_ms}, {:report, dropped + 1, now_ms - reported}}

      true ->
        {%{flow | dropped: dropped + 1}, nil}
    end
  end

  # What the connection carries out (see the moduledoc); `who` names its user in the log.

  @doc """
  A frame from the client of `who` (a user name), received at `now_ms`, counted (`frame/2`):
  the priority when it changed, and a warning for the frame that exceeds the pilot's budget.

      iex> alias NeptunusWeb.Socket.FlowControl
      iex> flow = FlowControl.new(pilot_frames_per_s: 1, backlog: 8)
      iex> flow = FlowControl.piloting(flow, "vehicle:a", true)
      iex> {flow, []} = FlowControl.frame_received(flow, 0, "ada")
      iex> {_flow, [{:log, :warning, line}, {:priority, :normal}]} =
      ...>   FlowControl.frame_received(flow, 1, "ada")
      iex> line
      "pilot \\"ada\\" sends more than 1 frames/s: its connection runs at :normal " <>
        "for the rest of this second"
  """
  @spec frame_received(t(), integer(), String.t()) :: {t(), [effect()]}
  def frame_received(%__MODULE__{} = flow, now_ms, who) do
    {next, verdict} = frame(flow, now_ms)

    warning =
      if verdict == :over_budget,
        do: [
          {:log, :warning,
           "pilot #{inspect(who)} sends more than #{next.frame_limit} frames/s: its " <>
             "connection runs at :normal for the rest of this second"}
        ],
        else: []

    {next, warning ++ priority_change(flow, next)}
  end

  @doc """
  The helm granted (`true`) or took back (`false`) control of `topic`'s vehicle
  (`piloting/3`): the pilot's connection gets its telemetry first, and its priority when it
  changed.

      iex> alias NeptunusWeb.Socket.FlowControl
      iex> flow = FlowControl.new(pilot_frames_per_s: 200, backlog: 8)
      iex> {flow, effects} = FlowControl.control_changed(flow, "vehicle:a", true)
      iex> effects
      [{:prioritize, "vehicle:a", true}, {:priority, :high}]
      iex> {_flow, effects} = FlowControl.control_changed(flow, "vehicle:a", false)
      iex> effects
      [{:prioritize, "vehicle:a", false}, {:priority, :low}]
  """
  @spec control_changed(t(), String.t(), boolean()) :: {t(), [effect()]}
  def control_changed(%__MODULE__{} = flow, topic, granted?) do
    next = piloting(flow, topic, granted?)
    {next, [{:prioritize, topic, granted?} | priority_change(flow, next)]}
  end

  @doc """
  A telemetry frame for the client of `who` dropped at `now_ms` (`dropped/2`): the log line
  when the drops are to be reported.

      iex> alias NeptunusWeb.Socket.FlowControl
      iex> flow = FlowControl.new(pilot_frames_per_s: 200, backlog: 8)
      iex> {flow, [{:log, :info, first}]} = FlowControl.telemetry_dropped(flow, 0, "ada")
      iex> first
      "\\"ada\\" reads slower than its telemetry arrives: dropped 1 stale telemetry frame(s)"
      iex> {flow, []} = FlowControl.telemetry_dropped(flow, 1_000, "ada")
      iex> {_flow, [{:log, :info, later}]} = FlowControl.telemetry_dropped(flow, 61_000, "ada")
      iex> later
      "\\"ada\\" reads slower than its telemetry arrives: " <>
        "dropped 2 stale telemetry frame(s) in the last 61 s"
  """
  @spec telemetry_dropped(t(), integer(), String.t()) :: {t(), [effect()]}
  def telemetry_dropped(%__MODULE__{} = flow, now_ms, who) do
    case dropped(flow, now_ms) do
      {flow, {:report, count, since_ms}} ->
        {flow,
         [
           {:log, :info,
            "#{inspect(who)} reads slower than its telemetry arrives: dropped #{count} stale " <>
              "telemetry frame(s)" <>
              if(since_ms == nil, do: "", else: " in the last #{div(since_ms, 1000)} s")}
         ]}

      {flow, nil} ->
        {flow, []}
    end
  end

  defp priority_change(before, next) do
    priority = priority(next)
    if priority == priority(before), do: [], else: [{:priority, priority}]
  end
end
