defmodule Neptunus.Test.ChaosClient do
  @moduledoc """
  A WebSocket client for the chaos test that behaves like the operator page: it connects,
  joins a vehicle's topic and, as a pilot, asks for control and, once granted, sends thrust
  and a heartbeat every `tick_ms`. When its connection closes it connects and joins again
  (retrying while the server restarts); when it is not in control it asks again every tick.

  It reports to `report` (the test process), each with the monotonic time in ms:

    * `{:chaos_client, name, :joined, t}`,
    * `{:chaos_client, name, :granted, t}`,
    * `{:chaos_client, name, {:stopped, reason}, t}` — a `stopped` event,
    * `{:chaos_client, name, :control_lost, t}` — a `control_lost` event or a command refused,
    * `{:chaos_client, name, {:link, up, reason}, t}` — a `link` event,
    * `{:chaos_client, name, :closed, t}` — its connection closed.

  `ws/1` gives its current `NeptunusWeb.Test.WSClient` (nil between connections).
  """
  alias NeptunusWeb.Test.{Wire, WSClient}

  defstruct [:name, :topic, :report, :pilot?, :ws, :jr, :epoch, tick_ms: 50, in_control: false]

  @type t :: %__MODULE__{}

  @doc "Starts a client (linked): `name`, `topic`, `pilot?`, reporting to the caller."
  @spec start_link(String.t(), String.t(), boolean()) :: pid()
  def start_link(name, topic, pilot?) do
    report = self()

    spawn_link(fn ->
      loop(connect(%__MODULE__{name: name, topic: topic, report: report, pilot?: pilot?}))
    end)
  end

  @doc "The client's current WebSocket client process, or nil."
  @spec ws(pid()) :: pid() | nil
  def ws(client) do
    ref = make_ref()
    send(client, {:ws?, self(), ref})

    receive do
      {^ref, ws} -> ws
    after
      2_000 -> nil
    end
  end

  defp now, do: System.monotonic_time(:millisecond)

  defp report(state, what), do: send(state.report, {:chaos_client, state.name, what, now()})

  defp connect(state) do
    query = URI.encode_query(%{"name" => state.name, "vsn" => "2.0.0"})

    # a short handshake timeout: a connection the endpoint accepted as it went down is
    # given up soon and tried again, as a browser's socket retries
    with {:ok, ws} <- WSClient.connect(Wire.port(), "/socket/websocket?" <> query, timeout: 500),
         jr = WSClient.unique_ref(),
         {:ok, _snapshot} <- safe_join(ws, state.topic, jr) do
      report(state, :joined)
      send(self(), {:tick, ws})
      %{state | ws: ws, jr: jr, in_control: false, epoch: nil}
    else
      _ ->
        Process.sleep(50)
        connect(state)
    end
  end

  defp safe_join(ws, topic, jr) do
    WSClient.join(ws, topic, %{}, jr)
  catch
    _, _ ->
      WSClient.close(ws)
      :error
  end

  defp loop(state) do
    receive do
      {:ws?, from, ref} ->
        send(from, {ref, state.ws})
        loop(state)

      # one tick chain per connection: ticks of an earlier one end with it
      {:tick, ws} when ws == state.ws ->
        Process.send_after(self(), {:tick, ws}, state.tick_ms)
        loop(tick(state))

      {:ws, ws, {:text, text}} when ws == state.ws ->
        loop(frame(state, :jiffy.decode(text, [:return_maps, {:null_term, nil}])))

      {:ws, ws, {:close, _, _}} when ws == state.ws ->
        reconnect(state)

      {:ws, ws, :closed} when ws == state.ws ->
        reconnect(state)

      _other ->
        loop(state)
    end
  end

  defp reconnect(state) do
    report(state, :closed)
    WSClient.close(state.ws)
    loop(connect(%{state | ws: nil}))
  end

  defp tick(%{pilot?: false} = state), do: state

  defp tick(%{in_control: false} = state) do
    push(state, "request_control:" <> WSClient.unique_ref(), "request_control", %{})
    state
  end

  defp tick(state) do
    push(state, "thrust:" <> WSClient.unique_ref(), "thrust", Wire.thrust(0.5, state.epoch))
    push(state, "heartbeat:" <> WSClient.unique_ref(), "heartbeat", %{})
    state
  end

  defp push(state, ref, event, payload),
    do: WSClient.push(state.ws, state.jr, ref, state.topic, event, payload)

  defp frame(state, [_, "request_control:" <> _, _, "phx_reply", %{"status" => "ok"} = reply]) do
    case reply["response"] do
      %{"status" => "granted", "grant" => %{"epoch" => epoch}} -> granted(state, epoch)
      _ -> state
    end
  end

  defp frame(state, [_, _, _, "control_granted", payload]),
    do: granted(state, payload["epoch"] || get_in(payload, ["grant", "epoch"]))

  defp frame(%{in_control: true} = state, [_, _, _, "control_lost", _]) do
    report(state, :control_lost)
    %{state | in_control: false}
  end

  defp frame(%{in_control: true} = state, [_, "thrust:" <> _, _, "phx_reply", reply]) do
    case reply do
      %{"status" => "ok"} ->
        state

      _ ->
        report(state, :control_lost)
        %{state | in_control: false}
    end
  end

  defp frame(state, [_, _, _, "stopped", payload]) do
    report(state, {:stopped, payload["reason"]})
    state
  end

  defp frame(state, [_, _, _, "link", %{"up" => up} = payload]) do
    report(state, {:link, up, payload["reason"]})
    state
  end

  defp frame(state, _frame), do: state

  defp granted(%{in_control: true} = state, _epoch), do: state

  defp granted(state, epoch) do
    report(state, :granted)
    %{state | in_control: true, epoch: epoch}
  end
end
