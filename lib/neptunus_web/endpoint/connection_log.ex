defmodule NeptunusWeb.Endpoint.ConnectionLog do
  @moduledoc """
  Counts the connections the endpoint closes to protect itself, and says so in the log in
  one line at most every `:report_ms` (10 s) instead of one line per connection.

  yaws logs an error (through `error_logger`) for every connection it closes beyond
  `max_connections`; under a flood
  that is thousands of lines a second, which would bury everything else and fill the
  journal. A primary logger filter (`filter/2`, installed while this process runs) drops
  that message and counts it; `NeptunusWeb.Endpoint.HeaderDeadline` counts the connections it
  closes for a slow head (`closed_slow/1`). Every second this process looks at the counts; when
  there are some and the last report is `:report_ms` old, it logs one warning with both
  and starts counting again (`flush/0`: at once).

  The filter matches the text of yaws' log message, which no interface promises: this
  process starts only on a yaws version it was written for and refuses any other with a
  message (see `NeptunusWeb.Endpoint.Yaws`, "Modules that read yaws' internals").
  """
  use GenServer

  require Logger

  alias NeptunusWeb.Endpoint.Yaws

  # the yaws versions whose log message this module was written to match
  @yaws_versions ["2.1.1"]
  @reads "the text of its log message for a connection closed beyond max_connections"

  @filter_id :neptunus_connection_log
  @yaws_max_connections ~c"Max connections reached - closing conn to ~s~n"
  @refused 1
  @slow 2

  defstruct counters: nil, report_ms: 10_000, tick_ms: 1_000, last_report_ms: nil

  @type t :: %__MODULE__{
          counters: :counters.counters_ref() | nil,
          report_ms: pos_integer(),
          tick_ms: pos_integer(),
          last_report_ms: integer() | nil
        }

  @doc """
  Starts the log. Options: `:report_ms` (the least time between two reports, default
  10 000), `:tick_ms` (how often to look, default 1 000), `:yaws_version` (the yaws to check;
  default the one running).
  """
  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts), do: GenServer.start_link(__MODULE__, opts, name: __MODULE__)

  @doc """
  The logger filter: `:stop` (and counted) for yaws' message about a connection closed
  beyond `max_connections`, `:ignore` (let other filters decide) for everything else.
  """
  @spec filter(:logger.log_event(), :counters.counters_ref()) :: :stop | :ignore
  def filter(%{msg: {:report, %{format: @yaws_max_connections}}}, counters) do
    :counters.add(counters, @refused, 1)
    :stop
  end

  def filter(%{msg: {@yaws_max_connections, _args}}, counters) do
    :counters.add(counters, @refused, 1)
    :stop
  end

  def filter(_event, _counters), do: :ignore

  @doc "Logs what was counted now, whatever the time since the last report."
  @spec flush() :: :ok
  def flush, do: GenServer.call(__MODULE__, :flush)

  @doc "Counts `n` connections closed for taking too long over their request head."
  @spec closed_slow(non_neg_integer()) :: :ok
  def closed_slow(n) when is_integer(n) and n >= 0 do
    case :persistent_term.get({__MODULE__, :counters}, nil) do
      nil -> :ok
      counters -> :counters.add(counters, @slow, n)
    end
  end

  @doc """
  The report line for `refused` connections closed beyond the limit and `slow` ones closed
  for a slow head, or nil when both are 0.

      iex> NeptunusWeb.Endpoint.ConnectionLog.report(0, 0)
      nil
      iex> NeptunusWeb.Endpoint.ConnectionLog.report(120, 3)
      "closed 123 connections: 120 beyond the connection limit, 3 slower than the header timeout"
  """
  @spec report(non_neg_integer(), non_neg_integer()) :: String.t() | nil
  def report(0, 0), do: nil

  def report(refused, slow) do
    "closed #{refused + slow} connections: #{refused} beyond the connection limit, " <>
      "#{slow} slower than the header timeout"
  end

  @impl true
  def init(opts) do
    with :ok <- Yaws.supported(__MODULE__, @yaws_versions, @reads, opts) do
      Process.flag(:trap_exit, true)
      counters = :counters.new(2, [:write_concurrency])
      :persistent_term.put({__MODULE__, :counters}, counters)
      _ = :logger.remove_primary_filter(@filter_id)
      :ok = :logger.add_primary_filter(@filter_id, {&__MODULE__.filter/2, counters})

      state = %__MODULE__{
        counters: counters,
        report_ms: Keyword.get(opts, :report_ms, 10_000),
        tick_ms: Keyword.get(opts, :tick_ms, 1_000)
      }

      Process.send_after(self(), :tick, state.tick_ms)
      {:ok, state}
    end
  end

  @impl true
  def handle_call(:flush, _from, state),
    do: {:reply, :ok, log_counts(state, Neptunus.Clock.monotonic_ms())}

  @impl true
  def handle_info(:tick, state) do
    now = Neptunus.Clock.monotonic_ms()
    Process.send_after(self(), :tick, state.tick_ms)

    if state.last_report_ms == nil or now - state.last_report_ms >= state.report_ms,
      do: {:noreply, log_counts(state, now)},
      else: {:noreply, state}
  end

  def handle_info(_other, state), do: {:noreply, state}

  @impl true
  def terminate(_reason, _state) do
    _ = :logger.remove_primary_filter(@filter_id)
    :ok
  end

  defp log_counts(state, now) do
    case report(take(state.counters, @refused), take(state.counters, @slow)) do
      nil ->
        state

      line ->
        Logger.warning(line)
        %{state | last_report_ms: now}
    end
  end

  defp take(counters, index) do
    n = :counters.get(counters, index)
    :counters.sub(counters, index, n)
    n
  end
end
