defmodule NeptunusWeb.PilotBudget do
  @moduledoc """
  How many frames per second a piloting connection may send and keep its `:high` process
  priority (pure).

  A pilot's connection runs at `:high`, with the vehicle's control path (see
  `NeptunusWeb.Socket`), and `:high` work runs before all `:normal` and `:low` work. A client
  that sends more than `limit` frames within one second loses `:high` for the rest of that
  second (its connection runs at `:normal`), so a broken or hostile pilot client cannot
  starve the observers, the telemetry or the main station's takeover. The official client
  sends well under the default limit: thrust at the gamepad's rate, a helm heartbeat every
  100 ms, a socket heartbeat every 30 s.

      iex> b = NeptunusWeb.PilotBudget.new(2)
      iex> {:within, b} = NeptunusWeb.PilotBudget.frame(b, 0)
      iex> {:within, b} = NeptunusWeb.PilotBudget.frame(b, 10)
      iex> {:over, b} = NeptunusWeb.PilotBudget.frame(b, 20)
      iex> {verdict, _} = NeptunusWeb.PilotBudget.frame(b, 1_000)
      iex> verdict
      :within
  """

  @window_ms 1_000

  @enforce_keys [:limit]
  defstruct [:limit, window_start: nil, count: 0]

  @type t :: %__MODULE__{
          limit: pos_integer(),
          window_start: integer() | nil,
          count: non_neg_integer()
        }

  @doc "A budget of `limit` frames per second."
  @spec new(pos_integer()) :: t()
  def new(limit) when is_integer(limit) and limit > 0, do: %__MODULE__{limit: limit}

  @doc """
  Counts one frame received at `now_ms` (a monotonic clock in milliseconds): `:within` while
  the frames of the current one-second window are at most `limit`, `:over` after.
  """
  @spec frame(t(), integer()) :: {:within | :over, t()}
  def frame(%__MODULE__{window_start: start} = budget, now_ms) when is_integer(now_ms) do
    budget =
      if start == nil or now_ms - start >= @window_ms or now_ms < start,
        do: %{budget | window_start: now_ms, count: 1},
        else: %{budget | count: budget.count + 1}

    {if(budget.count <= budget.limit, do: :within, else: :over), budget}
  end
end
