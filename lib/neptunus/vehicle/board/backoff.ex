defmodule Neptunus.Vehicle.Board.Backoff do
  @moduledoc """
  Reopen delays for a link: exponential from `min` to `max` ms, back to `min` once the link has
  stayed up for at least `max` ms (so a link that flaps open/closed backs off, and one that
  worked for a while is retried quickly after its next failure). Pure.

      iex> alias Neptunus.Vehicle.Board.Backoff
      iex> b = Backoff.new(100, 1000)
      iex> {d1, b} = Backoff.next(b)
      iex> {d2, b} = Backoff.next(b)
      iex> {d3, b} = Backoff.next(b)
      iex> {d4, b} = Backoff.next(b)
      iex> {d5, _} = Backoff.next(b)
      iex> [d1, d2, d3, d4, d5]
      [100, 200, 400, 800, 1000]
      iex> {d, _} = b |> Backoff.up_for(1000) |> Backoff.next()
      iex> d
      100
  """

  @enforce_keys [:min, :max, :next]
  defstruct [:min, :max, :next]

  @typedoc "`next` is the delay the next failure will wait, in ms."
  @type t :: %__MODULE__{min: pos_integer(), max: pos_integer(), next: pos_integer()}

  @doc "Delays from `min_ms` doubling up to `max_ms`."
  @spec new(pos_integer(), pos_integer()) :: t()
  def new(min_ms, max_ms) when is_integer(min_ms) and min_ms > 0 and max_ms >= min_ms,
    do: %__MODULE__{min: min_ms, max: max_ms, next: min_ms}

  @doc "The delay before the next attempt, and the backoff for the failure after it."
  @spec next(t()) :: {pos_integer(), t()}
  def next(%__MODULE__{} = b), do: {b.next, %{b | next: min(b.next * 2, b.max)}}

  @doc "The link was up for `ms` before it went down: reset when that is at least `max`."
  @spec up_for(t(), non_neg_integer()) :: t()
  def up_for(%__MODULE__{} = b, ms) when ms >= b.max, do: %{b | next: b.min}
  def up_for(%__MODULE__{} = b, _ms), do: b
end
