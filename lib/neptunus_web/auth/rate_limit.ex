defmodule NeptunusWeb.Auth.RateLimit do
  @moduledoc """
  Login attempts per client address: a token bucket per address holding up to `capacity`
  attempts (config `login_attempts_per_minute`, default 10) and refilled at `capacity` per
  minute. Every attempt takes a token, successful or not; an empty bucket answers with the
  time until the next token.

  Started under `NeptunusWeb.Endpoint`. Addresses are what the server sees: behind a reverse
  proxy every client has the proxy's address and shares its bucket.

      iex> alias NeptunusWeb.Auth.RateLimit
      iex> {:ok, b} = RateLimit.take(nil, 0, 2)
      iex> {:ok, b} = RateLimit.take(b, 0, 2)
      iex> RateLimit.take(b, 0, 2)
      {:error, 30_000}
      iex> {:ok, _} = RateLimit.take(b, 30_000, 2)
  """
  use GenServer

  @minute_ms 60_000
  @sweep_ms @minute_ms

  @typedoc "Tokens left (a float: the refill is continuous) and when that was computed (ms)."
  @type bucket :: {float(), integer()}

  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts \\ []), do: GenServer.start_link(__MODULE__, opts, name: __MODULE__)

  @doc "Takes one attempt for `address`: `:ok`, or `{:error, retry_after_ms}`."
  @spec check(term(), pos_integer()) :: :ok | {:error, pos_integer()}
  def check(address, capacity), do: GenServer.call(__MODULE__, {:check, address, capacity})

  @doc "Forgets every address (tests)."
  @spec reset() :: :ok
  def reset, do: GenServer.call(__MODULE__, :reset)

  @doc "Takes a token from `bucket` (nil: a new, full bucket) at `now` (ms)."
  @spec take(bucket() | nil, integer(), pos_integer()) ::
          {:ok, bucket()} | {:error, pos_integer()}
  def take(nil, now, capacity), do: take({capacity * 1.0, now}, now, capacity)

  def take({tokens, at}, now, capacity) do
    rate = capacity / @minute_ms
    tokens = min(capacity * 1.0, tokens + max(now - at, 0) * rate)

    if tokens >= 1.0,
      do: {:ok, {tokens - 1.0, now}},
      else: {:error, max(ceil((1.0 - tokens) / rate), 1)}
  end

  # Callbacks

  @impl true
  def init(_opts) do
    Process.send_after(self(), :sweep, @sweep_ms)
    {:ok, %{}}
  end

  @impl true
  def handle_call({:check, address, capacity}, _from, buckets) do
    case take(Map.get(buckets, address), now_ms(), capacity) do
      {:ok, bucket} -> {:reply, :ok, Map.put(buckets, address, bucket)}
      {:error, retry_ms} -> {:reply, {:error, retry_ms}, buckets}
    end
  end

  def handle_call(:reset, _from, _buckets), do: {:reply, :ok, %{}}

  @impl true
  def handle_info(:sweep, buckets) do
    # a bucket untouched for a minute is full again: forget it
    cutoff = now_ms() - @minute_ms
    Process.send_after(self(), :sweep, @sweep_ms)
    {:noreply, Map.reject(buckets, fn {_address, {_tokens, at}} -> at < cutoff end)}
  end

  defp now_ms, do: Neptunus.Clock.monotonic_ms()
end
