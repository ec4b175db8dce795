defmodule NeptunusWeb.Test.Wire do
  @moduledoc """
  Phoenix Channels helpers over `NeptunusWeb.Test.WSClient` for the wire tests against the
  running endpoint: connect (with query parameters and headers), join, push and wait for
  the reply, wait for an event. They run in the test process (the client's owner) and fail
  the test on timeouts.
  """
  import ExUnit.Assertions

  alias NeptunusWeb.Test.WSClient

  @doc "The endpoint's port."
  @spec port() :: :inet.port_number()
  def port, do: Application.fetch_env!(:neptunus, :endpoint).port

  @doc """
  A raw HTTP/1.1 GET of `path`: `{status, headers, body read so far, socket}` (header names
  in lower case; the socket to read the rest of the body from, as the server sent it —
  chunked or not).
  """
  @spec raw_get(String.t()) ::
          {integer(), %{String.t() => String.t()}, binary(), :gen_tcp.socket()}
  def raw_get(path), do: raw_request("GET", path, [{"Host", "127.0.0.1:#{port()}"}])

  @doc """
  A raw HTTP/1.1 request with exactly `headers` (`[{name, value}]`, nothing added): as
  `raw_get/1`, `{status, headers, body read so far, socket}`.
  """
  @spec raw_request(String.t(), String.t(), [{String.t(), String.t()}]) ::
          {integer(), %{String.t() => String.t()}, binary(), :gen_tcp.socket()}
  def raw_request(method, path, headers) do
    {:ok, socket} =
      :gen_tcp.connect(~c"127.0.0.1", port(), [:binary, active: false, packet: :raw])

    head = Enum.map(headers, fn {k, v} -> "#{k}: #{v}\r\n" end)
    :ok = :gen_tcp.send(socket, ["#{method} #{path} HTTP/1.1\r\n", head, "\r\n"])
    {head, body} = read_head(socket, <<>>)
    [status_line | header_lines] = String.split(head, "\r\n")
    [_, status | _] = String.split(status_line, " ")

    headers =
      Map.new(header_lines, fn line ->
        [k, v] = String.split(line, ":", parts: 2)
        {String.downcase(k), String.trim(v)}
      end)

    {String.to_integer(status), headers, body, socket}
  end

  defp read_head(socket, acc) do
    case :binary.split(acc, "\r\n\r\n") do
      [head, rest] ->
        {head, rest}

      [_] ->
        {:ok, data} = :gen_tcp.recv(socket, 0, Neptunus.Test.Patience.ms())
        read_head(socket, acc <> data)
    end
  end

  @doc "Connects with `params` (vsn added) and `headers`; `{:ok, ws}` or the client's error."
  @spec connect(map() | keyword(), keyword()) :: {:ok, pid()} | {:error, term()}
  def connect(params \\ %{}, headers \\ []) do
    query = params |> Map.new() |> Map.put("vsn", "2.0.0") |> URI.encode_query()
    WSClient.connect(port(), "/socket/websocket?" <> query, headers: headers)
  end

  @doc "Connects or fails."
  @spec connect!(map() | keyword(), keyword()) :: pid()
  def connect!(params \\ %{}, headers \\ []) do
    {:ok, ws} = connect(params, headers)
    ws
  end

  @doc "Joins `topic`; returns `{join_ref, reply}`."
  @spec join!(pid(), String.t()) :: {String.t(), map()}
  def join!(ws, topic) do
    join_ref = WSClient.unique_ref()
    assert {:ok, response} = WSClient.join(ws, topic, %{}, join_ref)
    {join_ref, response}
  end

  @doc "Pushes `event` and returns `{status, response}` of its reply (other frames skipped)."
  @spec push_and_reply(pid(), String.t(), String.t(), String.t(), map()) :: {String.t(), map()}
  def push_and_reply(ws, join_ref, topic, event, payload) do
    ref = WSClient.unique_ref()
    WSClient.push(ws, join_ref, ref, topic, event, payload)

    [^join_ref, ^ref, ^topic, "phx_reply", %{"status" => status, "response" => response}] =
      WSClient.recv_until(ws, &match?([_, ^ref, _, "phx_reply", _], &1))

    {status, response}
  end

  @doc "Waits for `event` whose payload satisfies `pred`; returns the payload."
  @spec event!(pid(), String.t(), (map() -> as_boolean(term())), timeout()) :: map()
  def event!(ws, event, pred \\ fn _ -> true end, timeout \\ Neptunus.Test.Patience.ms()) do
    [_, _, _, ^event, payload] =
      WSClient.recv_until(
        ws,
        &(match?([_, _, _, ^event, _], &1) and pred.(Enum.at(&1, 4))),
        timeout
      )

    payload
  end

  @doc """
  Waits until each of `events` has arrived (in any order, other frames skipped); returns
  `%{event => payload}` with the first payload of each. An entry may be `{event, pred}` to
  wait for a payload satisfying `pred`.
  """
  @spec collect!(pid(), [String.t() | {String.t(), (map() -> as_boolean(term()))}], timeout()) ::
          %{String.t() => map()}
  def collect!(ws, events, timeout \\ Neptunus.Test.Patience.ms()) do
    deadline = System.monotonic_time(:millisecond) + timeout

    wanted =
      Map.new(events, fn
        {event, pred} -> {event, pred}
        event -> {event, fn _ -> true end}
      end)

    collect_until(ws, wanted, %{}, deadline)
  end

  defp collect_until(_ws, wanted, seen, _deadline) when map_size(wanted) == 0, do: seen

  defp collect_until(ws, wanted, seen, deadline) do
    remaining = max(deadline - System.monotonic_time(:millisecond), 1)

    match? = fn [_, _, _, event, payload] ->
      case Map.fetch(wanted, event) do
        {:ok, pred} -> pred.(payload)
        :error -> false
      end
    end

    [_, _, _, event, payload] = WSClient.recv_until(ws, match?, remaining)
    collect_until(ws, Map.delete(wanted, event), Map.put(seen, event, payload), deadline)
  end

  @doc "No `event` arrives within `ms` (frames received meanwhile are consumed)."
  @spec no_event!(pid(), String.t(), non_neg_integer()) :: :ok
  def no_event!(ws, event, ms) do
    deadline = System.monotonic_time(:millisecond) + ms
    no_event_until(ws, event, deadline)
  end

  defp no_event_until(ws, event, deadline) do
    remaining = deadline - System.monotonic_time(:millisecond)

    receive do
      {:ws, ^ws, {:text, text}} ->
        frame = :jiffy.decode(text, [:return_maps, {:null_term, nil}])
        refute match?([_, _, _, ^event, _], frame), "unexpected #{event}: #{text}"
        no_event_until(ws, event, deadline)
    after
      max(remaining, 0) -> :ok
    end
  end

  @doc "A motion thrust payload, stamped with `epoch` unless it is nil."
  @spec thrust(number(), integer() | nil) :: map()
  def thrust(surge, epoch \\ nil) do
    payload = %{"mode" => "motion", "surge" => surge, "heave" => 0, "yaw" => 0}
    if epoch, do: Map.put(payload, "epoch", epoch), else: payload
  end

  @doc """
  Starts a simulated vehicle named `prefix-N` for the calling test (stopped when the test
  exits), with `options` of the vehicle (e.g. `position:` its position sources); returns
  `%{id: id, topic: "vehicle:" <> id}`. For `setup` blocks.
  """
  @spec start_vehicle!(String.t(), map()) :: %{id: String.t(), topic: String.t()}
  def start_vehicle!(prefix, options \\ %{}) do
    id = "#{prefix}-#{System.unique_integer([:positive])}"
    {:ok, _} = Neptunus.Fleet.start_vehicle(Map.merge(%{id: id, board: :simulated}, options))
    ExUnit.Callbacks.on_exit(fn -> Neptunus.Fleet.stop_vehicle(id) end)
    %{id: id, topic: "vehicle:" <> id}
  end

  @doc "Connects with `params` and joins `topic`: `%{ws, jr, topic, snapshot}`."
  @spec client!(String.t(), map()) :: %{
          ws: pid(),
          jr: String.t(),
          topic: String.t(),
          snapshot: map()
        }
  def client!(topic, params) do
    ws = connect!(params)
    {jr, snapshot} = join!(ws, topic)
    %{ws: ws, jr: jr, topic: topic, snapshot: snapshot}
  end

  @doc """
  Changes the running endpoint's settings (`NeptunusWeb.Endpoint.Settings`, read by every new
  connection and request) for the rest of the calling test: `changes` are fields of the
  settings, and an `auth` map is completed with local mode's defaults
  (`Neptunus.Config.Auth.local/0`). The previous settings come back when the test exits.
  """
  @spec settings!(keyword()) :: :ok
  def settings!(changes) do
    previous = NeptunusWeb.Endpoint.Settings.get()
    ExUnit.Callbacks.on_exit(fn -> NeptunusWeb.Endpoint.Settings.put(previous) end)

    changes =
      case Keyword.fetch(changes, :auth) do
        {:ok, auth} -> Keyword.put(changes, :auth, Map.merge(Neptunus.Config.Auth.local(), auth))
        :error -> changes
      end

    NeptunusWeb.Endpoint.Settings.put(struct!(previous, changes))
  end

  @doc """
  Switches the running endpoint to secure mode with `secret` and `users`
  (`%{name => %{name, role, hash}}`) for the rest of the calling test (`settings!/1`);
  `overrides` change other security settings.
  """
  @spec secure!(String.t(), map(), map()) :: :ok
  def secure!(secret, users, overrides \\ %{}) do
    config = %{
      mode: :secure,
      secret: secret,
      users: users,
      anonymous_observers: false,
      origins: [],
      token_ttl_s: 600,
      login_attempts_per_minute: 10
    }

    settings!(auth: Map.merge(config, overrides))
  end
end
