defmodule NeptunusWeb.Test.Conformance do
  @moduledoc """
  A Phoenix Channels client for the wire-schema conformance tests: every frame it receives
  is checked against `NeptunusWeb.WireSchema` the moment it arrives — a join reply against
  the topic's join type, a reply against the command's reply (`ok`) or `{"reason": string}`
  (`error`), an event against the topic's event — and the test fails with the frame and
  what is wrong in it. What it saw is counted (`seen/0`), so a test can tell which of the
  schema's messages it exercised.

  Runs in the test process (the socket's owner); frames received while waiting for another
  are kept for the next `await!/3`.
  """
  import ExUnit.Assertions

  alias Neptunus.Test.Patience
  alias NeptunusWeb.Test.{Wire, WSClient}
  alias NeptunusWeb.WireSchema
  alias NeptunusWeb.WireSchema.Check

  @typedoc "A connection joined to one topic."
  @type client :: %{ws: pid(), jr: String.t(), topic: String.t(), join: map()}

  @doc "Connects with `params` and joins `topic`; the join reply is checked."
  @spec join!(String.t(), map()) :: client()
  def join!(topic, params \\ %{}) do
    ws = Wire.connect!(params)
    jr = WSClient.unique_ref()
    {"ok", reply} = push!(%{ws: ws, jr: jr, topic: topic, join: %{}}, "phx_join", %{})
    %{ws: ws, jr: jr, topic: topic, join: reply}
  end

  @doc """
  Pushes `event` with `payload` and returns `{status, response}` of its reply, checked
  against the schema. Events that arrive meanwhile are checked and kept.
  """
  @spec push!(client(), String.t(), map()) :: {String.t(), map()}
  def push!(c, event, payload \\ %{}) do
    ref = if event == "phx_join", do: c.jr, else: WSClient.unique_ref()
    Process.put({__MODULE__, :pushed, ref}, {c.topic, event})
    :ok = WSClient.push(c.ws, c.jr, ref, c.topic, event, payload)

    [_, _, _, _, %{"status" => status, "response" => response}] =
      take!(c, &match?([_, ^ref, _, "phx_reply", _], &1), Patience.ms())

    {status, response}
  end

  @doc "Waits for `event` whose payload satisfies `pred` (checked, as every frame); returns the payload."
  @spec await!(client(), String.t(), (map() -> as_boolean(term())), timeout()) :: map()
  def await!(c, event, pred \\ fn _ -> true end, timeout \\ Patience.ms()) do
    [_, _, _, ^event, payload] =
      take!(c, &(match?([_, _, _, ^event, _], &1) and pred.(Enum.at(&1, 4))), timeout)

    payload
  end

  @doc "The `{kind, topic, name}` of every message checked so far in this process."
  @spec seen() :: MapSet.t()
  def seen, do: Process.get({__MODULE__, :seen}, MapSet.new())

  defp take!(c, match?, timeout) do
    kept = Process.get({__MODULE__, :kept, c.ws}, [])

    case Enum.split_while(kept, &(not match?.(&1))) do
      {before, [frame | rest]} ->
        Process.put({__MODULE__, :kept, c.ws}, before ++ rest)
        frame

      {_, []} ->
        deadline = System.monotonic_time(:millisecond) + timeout
        receive_until(c, match?, deadline)
    end
  end

  defp receive_until(c, match?, deadline) do
    remaining = max(deadline - System.monotonic_time(:millisecond), 0)
    frame = WSClient.recv_frame(c.ws, remaining)
    check_frame!(frame)

    if match?.(frame) do
      frame
    else
      Process.put(
        {__MODULE__, :kept, c.ws},
        Process.get({__MODULE__, :kept, c.ws}, []) ++ [frame]
      )

      receive_until(c, match?, deadline)
    end
  end

  defp check_frame!([_, ref, topic, _, _] = frame) do
    pushed =
      case Process.get({__MODULE__, :pushed, ref}) do
        {^topic, event} -> event
        _ -> nil
      end

    conform_frame!(frame, pushed)
  end

  @doc """
  Checks a received frame: a `phx_reply` to `pushed` (the event this client pushed with the
  frame's ref) against the command's reply or the topic's join reply, any other frame
  against the topic's event. `opts` go to `NeptunusWeb.WireSchema.Check.check/3`.
  """
  @spec conform_frame!(list(), String.t() | nil, keyword()) :: :ok
  def conform_frame!(frame, pushed, opts \\ [])

  def conform_frame!([_, _, _, "phx_reply", _] = frame, nil, _opts),
    do: flunk("a reply to nothing this client pushed: #{inspect(frame)}")

  def conform_frame!([_, _, topic, "phx_reply", reply] = frame, pushed, opts) do
    %{"status" => status, "response" => response} = reply
    kind = topic_kind(topic)

    case {status, pushed} do
      {"error", _} ->
        conform!({:reply_error, kind, pushed}, :reason, response, frame, opts)

      {"ok", "phx_join"} ->
        join = Enum.find(WireSchema.joins(), &(&1.topic == kind))
        conform!({:join, kind, pushed}, join.payload, response, frame, opts)

      {"ok", _} ->
        reply_type = WireSchema.command!(kind, pushed).reply
        conform!({:reply, kind, pushed}, reply_type, response, frame, opts)
    end
  end

  def conform_frame!([_, _, _, event, _], _pushed, _opts)
      when event in ["phx_close", "phx_error"],
      do: :ok

  def conform_frame!([_, _, topic, event, payload] = frame, _pushed, opts) do
    kind = topic_kind(topic)
    conform!({:event, kind, event}, WireSchema.event!(kind, event), payload, frame, opts)
  end

  @doc "Checks `payload` (JSON, as a client receives it) against `type`, or fails the test."
  @spec conform!(term(), WireSchema.type(), term(), term(), keyword()) :: :ok
  def conform!(what, type, payload, context \\ nil, opts \\ []) do
    Process.put({__MODULE__, :seen}, MapSet.put(seen(), what))

    case Check.check(type, payload, opts) do
      :ok ->
        :ok

      {:error, problems} ->
        flunk("""
        #{inspect(what)} does not conform to the wire schema (#{inspect(type)}):
          #{Enum.join(problems, "\n  ")}
        in #{inspect(context || payload, limit: :infinity, printable_limit: 2_000)}
        """)
    end
  end

  defp topic_kind("vehicle:" <> _), do: "vehicle"
  defp topic_kind("log:" <> _), do: "log"
  defp topic_kind("fleet"), do: "fleet"
end
