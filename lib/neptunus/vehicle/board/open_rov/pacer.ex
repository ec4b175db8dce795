defmodule Neptunus.Vehicle.Board.OpenROV.Pacer do
  @moduledoc """
  Paces the commands written to an OpenROV board so its 64-byte receive buffer never
  overflows. Pure: the board link (`Neptunus.Vehicle.Board.OpenROV.UART`) pushes commands and asks
  which may go out now; a timer is needed only while something is queued (`next_at/2`).

  The board's firmware reads its serial receive buffer (64 bytes; what does not fit is
  dropped) in its main loop, about every 10 ms, and its loop stalls for up to 20 ms about once a
  second (sensor reads). So the link writes:

    * **at most `window_bytes` (60) bytes in any `window_ms` (30 ms) window** — what a 30 ms
      stall can leave in the buffer, with room to spare;
    * **commands at least `spacing_ms` (3 ms) apart** — the spacing the OpenROV 30.x cockpit
      used between its writes.

  Commands are queued by key and coalesced: a newer command with the key of a queued one
  replaces it in its place in the queue (the newest `go()` replaces a queued `go()`, a device's
  newest value replaces its queued one). A command pushed as `sticky` (a neutral `go()`, a
  `stop()`) is never replaced by a later ordinary command: that one queues after it (and is
  itself replaced by newer ones); a newer sticky command replaces everything queued under its
  key, in the place of the first. So the board always gets every neutral it was sent, and
  at most two commands per key wait. Nothing is ever dropped otherwise. When nothing is queued
  and the limits allow, a pushed command goes out at once (`push/4` then `take/2` in the same
  millisecond).

  Times are integer milliseconds of one monotonic clock.
  """

  @enforce_keys [:window_ms, :window_bytes, :spacing_ms]
  defstruct [:window_ms, :window_bytes, :spacing_ms, queue: [], sent: [], last_at_ms: nil]

  @typedoc "What a command is coalesced by: `:go`, `{:device, :lights}`, `:ping`, …"
  @type key :: term()

  @typedoc """
  * `queue` — `{key, bytes, sticky}` in sending order
  * `sent` — `{at, size}` of the writes inside the current window, newest first
  * `last_at_ms` — when the last command was written
  """
  @type t :: %__MODULE__{
          window_ms: pos_integer(),
          window_bytes: pos_integer(),
          spacing_ms: non_neg_integer(),
          queue: [{key(), binary(), boolean()}],
          sent: [{integer(), pos_integer()}],
          last_at_ms: integer() | nil
        }

  @doc """
  A pacer; options `:window_ms` (30), `:window_bytes` (60), `:spacing_ms` (3).

      iex> p = Neptunus.Vehicle.Board.OpenROV.Pacer.new()
      iex> {p.window_ms, p.window_bytes, p.spacing_ms}
      {30, 60, 3}
  """
  @spec new(keyword()) :: t()
  def new(opts \\ []) do
    %__MODULE__{
      window_ms: Keyword.get(opts, :window_ms, 30),
      window_bytes: Keyword.get(opts, :window_bytes, 60),
      spacing_ms: Keyword.get(opts, :spacing_ms, 3)
    }
  end

  @doc """
  Queues `bytes` under `key`: it replaces the queued command of that key in its place, unless
  that one is sticky (then it queues after it); with `sticky: true` it replaces every queued
  command of its key and is never replaced itself (see the moduledoc). Returns
  `{:error, reason}` (pacer unchanged) for a command that could never be sent: empty, or
  longer than the window allows.
  """
  @spec push(t(), key(), binary(), keyword()) :: {:ok, t()} | {:error, String.t()}
  def push(pacer, key, bytes, opts \\ [])

  def push(%__MODULE__{} = p, _key, bytes, _opts)
      when not is_binary(bytes) or bytes == "" or byte_size(bytes) > p.window_bytes,
      do: {:error, "a command must be 1..#{p.window_bytes} bytes"}

  def push(%__MODULE__{} = p, key, bytes, opts) do
    entry = {key, bytes, Keyword.get(opts, :sticky, false)}
    {:ok, %{p | queue: enqueue(p.queue, entry)}}
  end

  # sticky: in the place of the first queued command of its key, all others of the key removed
  defp enqueue(queue, {key, _, true} = entry) do
    case Enum.find_index(queue, &(elem(&1, 0) == key)) do
      nil ->
        queue ++ [entry]

      i ->
        {before, rest} = Enum.split(queue, i)
        before ++ [entry | Enum.reject(rest, &(elem(&1, 0) == key))]
    end
  end

  # ordinary: replaces the last queued command of its key unless that one is sticky
  defp enqueue(queue, {key, _, false} = entry) do
    case queue
         |> Enum.with_index()
         |> Enum.filter(&(elem(elem(&1, 0), 0) == key))
         |> List.last() do
      {{_, _, false}, i} -> List.replace_at(queue, i, entry)
      _ -> queue ++ [entry]
    end
  end

  @doc """
  The commands that may be written at `now`, in order (at most one: commands go at least
  `spacing_ms` apart, and with `spacing_ms` 0 as many as the window allows), and the pacer
  that has sent them.
  """
  @spec take(t(), integer()) :: {[{key(), binary()}], t()}
  def take(%__MODULE__{} = p, now) do
    p = expire(p, now)
    take(p, now, [])
  end

  defp take(%__MODULE__{queue: [{key, bytes, _sticky} | rest]} = p, now, acc) do
    if ready?(p, now, byte_size(bytes)) do
      p = %{p | queue: rest, sent: [{now, byte_size(bytes)} | p.sent], last_at_ms: now}
      acc = [{key, bytes} | acc]
      if p.spacing_ms == 0, do: take(p, now, acc), else: {Enum.reverse(acc), p}
    else
      {Enum.reverse(acc), p}
    end
  end

  defp take(p, _now, acc), do: {Enum.reverse(acc), p}

  @doc """
  When the first queued command may go (≥ `now`), or nil when nothing is queued.
  """
  @spec next_at(t(), integer()) :: integer() | nil
  def next_at(%__MODULE__{queue: []}, _now), do: nil

  def next_at(%__MODULE__{queue: [{_key, bytes, _sticky} | _]} = p, now) do
    p = expire(p, now)
    spaced = if p.last_at_ms, do: p.last_at_ms + p.spacing_ms, else: now
    max(now, max(spaced, window_free_at(p, byte_size(bytes), now)))
  end

  @doc "Number of queued commands."
  @spec queued(t()) :: non_neg_integer()
  def queued(%__MODULE__{queue: queue}), do: length(queue)

  @doc "Drops everything queued (a closed link); the window history stays."
  @spec clear(t()) :: t()
  def clear(%__MODULE__{} = p), do: %{p | queue: []}

  defp ready?(p, now, size) do
    spaced? = p.last_at_ms == nil or now - p.last_at_ms >= p.spacing_ms
    spaced? and in_window(p) + size <= p.window_bytes
  end

  defp in_window(p), do: Enum.reduce(p.sent, 0, fn {_at, n}, sum -> sum + n end)

  # writes at `at` count while now - at < window_ms
  defp expire(p, now),
    do: %{p | sent: Enum.filter(p.sent, fn {at, _} -> now - at < p.window_ms end)}

  # the earliest time at which `size` more bytes fit: drop the oldest writes until they do
  defp window_free_at(p, size, now) do
    oldest_first = Enum.reverse(p.sent)
    free_at(oldest_first, in_window(p), size, p, now)
  end

  defp free_at(_sent, total, size, p, now) when total + size <= p.window_bytes, do: now

  defp free_at([{at, n} | rest], total, size, p, _now) do
    expires = at + p.window_ms

    if total - n + size <= p.window_bytes,
      do: expires,
      else: free_at(rest, total - n, size, p, expires)
  end
end
