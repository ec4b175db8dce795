defmodule Neptunus.Periodic do
  @moduledoc """
  A fixed-rate loop on absolute deadlines of the monotonic clock, in native units (the one
  place that uses them, see `Neptunus.Clock`: a period of 1 s / rate is exact in them).

  Re-arming a relative timer after each tick drifts (BEAM timers fire about 1 ms late at the
  median, so a 20 ms loop runs at ≈ 47.6 Hz); this schedules every tick against the ideal
  deadline `start + n · period` instead, and tells the caller how many periods have elapsed
  when a tick comes late, so it can catch up or skip.

      periodic = Periodic.new(100)       # 100 Hz
      Periodic.arm(periodic, :tick)      # :tick arrives at the first deadline
      # on :tick:
      {due, periodic} = Periodic.advance(periodic, Neptunus.Clock.monotonic_native())
      Periodic.arm(periodic, :tick)
  """

  @enforce_keys [:period, :next]
  defstruct [:period, :next]

  @typedoc "period and next deadline in native monotonic time units"
  @type t :: %__MODULE__{period: pos_integer(), next: integer()}

  @doc "A loop at `hz` ticks per second whose first deadline is one period after `now`."
  @spec new(pos_integer(), integer()) :: t()
  def new(hz, now \\ Neptunus.Clock.monotonic_native()) when is_integer(hz) and hz > 0 do
    period = div(System.convert_time_unit(1, :second, :native), hz)
    %__MODULE__{period: period, next: now + period}
  end

  @doc """
  Periods due at `now` (at least 1: the tick being handled) and the loop advanced past them.

      iex> p = %Neptunus.Periodic{period: 10, next: 100}
      iex> Neptunus.Periodic.advance(p, 100)
      {1, %Neptunus.Periodic{period: 10, next: 110}}
      iex> Neptunus.Periodic.advance(p, 135)
      {4, %Neptunus.Periodic{period: 10, next: 140}}
      iex> Neptunus.Periodic.advance(p, 99)
      {1, %Neptunus.Periodic{period: 10, next: 110}}
  """
  @spec advance(t(), integer()) :: {pos_integer(), t()}
  def advance(%__MODULE__{period: period, next: next} = p, now) do
    due = max(div(now - next, period) + 1, 1)
    {due, %{p | next: next + due * period}}
  end

  @doc "Sends `msg` to the calling process at the next deadline."
  @spec arm(t(), term()) :: reference()
  def arm(%__MODULE__{next: next}, msg) do
    Process.send_after(self(), msg, System.convert_time_unit(next, :native, :millisecond),
      abs: true
    )
  end
end
