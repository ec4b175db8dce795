defmodule NeptunusWeb.Endpoint.HeaderDeadline do
  @moduledoc """
  Closes a connection that takes longer than `NeptunusWeb.Endpoint.header_timeout_ms/0` to
  send a request's head, or to start its next request on a kept-alive connection.

  yaws bounds each read of the request line and of each header line (its
  `keepalive_timeout`), not the whole head: a client sending a short header line every second
  or so (a "slowloris") would hold its connection, and a descriptor, for as long as it likes.
  Every `interval_ms` this process looks at yaws' connection processes: one whose stack is in
  `yaws:http_recv_request/2` or `yaws:http_collect_headers/5` is reading a request head.
  Which head it reads: while reading headers, the request is told by yaws'
  `request_start_time` (set when a request line arrives); while waiting for a request line,
  by the bytes the server has sent on the connection — yaws clears its process dictionary
  after every request, so on a kept-alive connection only its answers tell one wait from the
  next (empty lines, which yaws skips with a fresh read timeout, send nothing). A process
  seen reading the same head (same phase, same request) for its `deadline/3` is killed: its
  socket closes, and yaws counts the connection as gone (`NeptunusWeb.Endpoint.ConnectionLog`
  counts it for the log). A connection that makes progress (its next request, its headers
  complete) starts a fresh deadline; WebSocket and streaming connections never read a head
  and are never touched.

  The decision is `sweep/4`, a pure function; this process only observes and kills. It runs
  in `NeptunusWeb.Endpoint`'s supervisor after yaws, and never fails on a process that ends
  while it looks.

  It reads yaws' internals (how yaws' acceptor starts, its functions on the stack, its
  `request_start_time` in the process dictionary): it starts only on a yaws version it was
  written for and refuses any other with a message (see `NeptunusWeb.Endpoint.Yaws`,
  "Modules that read yaws' internals").
  """
  use GenServer

  alias NeptunusWeb.Endpoint.Yaws

  # the yaws versions whose connection processes this module was written to read
  @yaws_versions ["2.1.1"]
  @reads "the stacks and process dictionaries of its connection processes"

  @typedoc """
  What a connection process is reading: the request line and the bytes sent on its socket
  so far, or headers and yaws' start time of their request.
  """
  @type key :: {:request_line, non_neg_integer() | nil} | {:headers, term()}

  @typedoc "Each connection reading a head: what it reads, since when (ms, monotonic)."
  @type seen :: %{pid() => {key(), integer()}}

  defstruct timeout_ms: 5_000, interval_ms: 1_000, seen: %{}

  @type t :: %__MODULE__{timeout_ms: pos_integer(), interval_ms: pos_integer(), seen: seen()}

  @doc """
  Starts the deadline. Options: `:timeout_ms` (required), `:interval_ms` (between sweeps;
  default a quarter of the timeout, 10..1000 ms), `:yaws_version` (the yaws to check;
  default the one running).
  """
  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts), do: GenServer.start_link(__MODULE__, opts, name: __MODULE__)

  @doc """
  One sweep: given the connections seen before, those reading a head now (`[{pid, key}]`),
  the time and the timeout (ms, or a function of the key giving it), returns the
  connections to remember and those to close. A connection is closed when it has been
  reading the same head for its timeout or more; one no longer reading a head is forgotten.

      iex> alias NeptunusWeb.Endpoint.HeaderDeadline
      iex> {seen, []} = HeaderDeadline.sweep(%{}, [{:a, {:headers, 1}}], 0, 5000)
      iex> {_, []} = HeaderDeadline.sweep(seen, [{:a, {:headers, 1}}], 4999, 5000)
      iex> HeaderDeadline.sweep(seen, [{:a, {:headers, 1}}], 5000, 5000)
      {%{}, [:a]}
      iex> HeaderDeadline.sweep(seen, [{:a, {:headers, 2}}], 5000, 5000)
      {%{a: {{:headers, 2}, 5000}}, []}
      iex> longer = fn {:headers, _} -> 6000 end
      iex> {_, []} = HeaderDeadline.sweep(seen, [{:a, {:headers, 1}}], 5000, longer)
  """
  @spec sweep(
          %{term() => {term(), integer()}},
          [{term(), term()}],
          integer(),
          pos_integer() | (term() -> pos_integer())
        ) :: {%{term() => {term(), integer()}}, [term()]}
  def sweep(seen, reading, now, timeout_ms) when is_integer(timeout_ms),
    do: sweep(seen, reading, now, fn _key -> timeout_ms end)

  def sweep(seen, reading, now, timeout_of) do
    Enum.reduce(reading, {%{}, []}, fn {pid, key}, {next, expired} ->
      case Map.fetch(seen, pid) do
        {:ok, {^key, since}} ->
          if now - since >= timeout_of.(key),
            do: {next, [pid | expired]},
            else: {Map.put(next, pid, {key, since}), expired}

        _ ->
          {Map.put(next, pid, {key, now}), expired}
      end
    end)
    |> then(fn {next, expired} -> {next, Enum.reverse(expired)} end)
  end

  @doc """
  The deadline of what a connection reads. A request line is awaited in one read, which
  yaws itself bounds by the same timeout (its `keepalive_timeout`): it closes an idle
  connection first, and this process gives it one more sweep, so that it only catches what
  yaws does not (empty lines, which yaws skips with a fresh read timeout). Headers are read
  line by line, each read bounded by yaws, the whole by the timeout.

      iex> NeptunusWeb.Endpoint.HeaderDeadline.deadline({:request_line, 0}, 5000, 1000)
      6000
      iex> NeptunusWeb.Endpoint.HeaderDeadline.deadline({:headers, {1, 2, 3}}, 5000, 1000)
      5000
  """
  @spec deadline(key(), pos_integer(), pos_integer()) :: pos_integer()
  def deadline({:request_line, _}, timeout_ms, interval_ms), do: timeout_ms + interval_ms
  def deadline({:headers, _}, timeout_ms, _interval_ms), do: timeout_ms

  @impl true
  def init(opts) do
    with :ok <- Yaws.supported(__MODULE__, @yaws_versions, @reads, opts) do
      timeout = Keyword.fetch!(opts, :timeout_ms)
      interval = Keyword.get(opts, :interval_ms, min(1_000, max(div(timeout, 4), 10)))
      state = %__MODULE__{timeout_ms: timeout, interval_ms: interval}
      schedule(state)
      {:ok, state}
    end
  end

  @impl true
  def handle_info(:sweep, state) do
    now = Neptunus.Clock.monotonic_ms()
    timeout_of = &deadline(&1, state.timeout_ms, state.interval_ms)
    {seen, expired} = sweep(state.seen, reading_heads(), now, timeout_of)

    Enum.each(expired, &Process.exit(&1, :kill))
    NeptunusWeb.Endpoint.ConnectionLog.closed_slow(length(expired))
    schedule(state)
    {:noreply, %{state | seen: seen}}
  end

  def handle_info(_other, state), do: {:noreply, state}

  @doc """
  The bytes sent so far on the TCP socket of yaws' connection process `pid`, or nil when it
  has none (it ended). Over plain TCP the socket's port is linked to the process; over TLS
  it belongs to ssl's connection process, which monitors its owner.
  """
  @spec sent_bytes(pid()) :: non_neg_integer() | nil
  def sent_bytes(pid) do
    with port when is_port(port) <- tcp_port(pid) || tls_tcp_port(pid),
         {:ok, [send_oct: n]} <- :inet.getstat(port, [:send_oct]) do
      n
    else
      _ -> nil
    end
  end

  defp tls_tcp_port(pid) do
    case Process.info(pid, :monitored_by) do
      {:monitored_by, pids} -> Enum.find_value(pids, &(is_pid(&1) and tcp_port(&1)))
      nil -> nil
    end
  end

  defp tcp_port(pid) do
    case Process.info(pid, :links) do
      {:links, links} -> Enum.find(links, &tcp_port?/1)
      nil -> nil
    end
  end

  defp tcp_port?(port) when is_port(port),
    do: :erlang.port_info(port, :name) == {:name, ~c"tcp_inet"}

  defp tcp_port?(_), do: false

  defp schedule(state), do: Process.send_after(self(), :sweep, state.interval_ms)

  # yaws' connection processes that are reading a request head, with what they read.
  defp reading_heads do
    for server <- gservs(), pid <- links(server), key = head_key(pid), key != nil, do: {pid, key}
  end

  # yaws' listener processes: linked to the yaws_server process.
  defp gservs do
    case Process.whereis(:yaws_server) do
      nil -> []
      pid -> links(pid)
    end
  end

  defp links(pid) do
    case Process.info(pid, :links) do
      {:links, links} -> Enum.filter(links, &is_pid/1)
      nil -> []
    end
  end

  defp head_key(pid) do
    case Process.info(pid, [:current_stacktrace, :dictionary]) do
      [current_stacktrace: stack, dictionary: dictionary] ->
        if Keyword.get(dictionary, :"$initial_call") == {:yaws_server, :acceptor0, 2} do
          case phase(stack) do
            nil -> nil
            :headers -> {:headers, Keyword.get(dictionary, :request_start_time)}
            :request_line -> {:request_line, sent_bytes(pid)}
          end
        end

      _ ->
        nil
    end
  end

  defp phase(stack) do
    Enum.find_value(stack, fn
      {:yaws, :http_recv_request, _, _} -> :request_line
      {:yaws, :http_collect_headers, _, _} -> :headers
      _ -> nil
    end)
  end
end
