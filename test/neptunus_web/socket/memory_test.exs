defmodule NeptunusWeb.Socket.MemoryTest do
  # A WebSocket connection's memory (NeptunusWeb.Socket, "Memory"), against the running
  # endpoint with a real client: no private copies of broadcast frames, full-sweep
  # collections only, hibernation when idle.
  use ExUnit.Case, async: false

  alias NeptunusWeb.Test.WSClient

  @moduletag :capture_log

  setup do
    id = "mem-#{System.unique_integer([:positive])}"
    # the vehicle streams its own telemetry too; the test's frames are told apart by "k"
    {:ok, _} = Neptunus.Fleet.start_vehicle(%{id: id, board: :simulated})
    on_exit(fn -> Neptunus.Fleet.stop_vehicle(id) end)
    {:ok, topic: "vehicle:" <> id}
  end

  defp port, do: Application.fetch_env!(:neptunus, :endpoint).port

  # a connection and its server-side process (yaws' WebSocket process)
  defp connect!(name) do
    before = ws_pids()

    {:ok, ws} = WSClient.connect(port(), "/socket/websocket?vsn=2.0.0&name=#{URI.encode(name)}")

    pid =
      Neptunus.Test.Pty.wait_until(
        fn ->
          case ws_pids() -- before do
            [pid] -> pid
            _ -> nil
          end
        end,
        "the connection process"
      )

    {ws, pid}
  end

  defp ws_pids,
    do: for({_, pid, _, _} <- Supervisor.which_children(:yaws_ws_sup), is_pid(pid), do: pid)

  defp join!(ws, topic) do
    {:ok, _} = WSClient.join(ws, topic, %{}, WSClient.unique_ref())
    :ok
  end

  defp telemetry!(ws, topic, k),
    do: WSClient.recv_until(ws, &match?([_, _, ^topic, "telemetry", %{"k" => ^k}], &1))

  test "a broadcast frame goes out as the shared binary: the connection holds no copy of it",
       %{topic: topic} do
    {ws, pid} = connect!("Copy")
    join!(ws, topic)
    pad = String.duplicate("x", 100_000)
    # a clean heap: nothing the frame's handling leaves behind is collected before we look
    :erlang.garbage_collect(pid)

    Neptunus.PubSub.broadcast(topic, "telemetry", %{"k" => 1, "pad" => pad})
    assert [_, _, ^topic, "telemetry", %{"pad" => ^pad}] = telemetry!(ws, topic, 1)

    {:binary, binaries} = Process.info(pid, :binary)
    sizes = for {_, size, _} <- binaries, do: size
    # the encoded frame is ~100 kB; a copy with its 10-byte WebSocket header would be one more
    # binary of that size held by this process alone
    big = Enum.filter(binaries, fn {_, size, _} -> size > 100_000 end)
    assert Enum.all?(big, fn {_, size, _} -> size < 100_100 end), inspect(sizes)
    assert length(big) <= 1, inspect(sizes)
  end

  test "the connection process collects with full sweeps only: no old heap after a burst",
       %{topic: topic} do
    {ws, pid} = connect!("Burst")
    join!(ws, topic)

    assert {:fullsweep_after, 0} =
             List.keyfind(elem(Process.info(pid, :garbage_collection), 1), :fullsweep_after, 0)

    sample = %{"depth" => 1.25, "heading" => 271.5, "pad" => String.duplicate("t", 1_200)}
    for k <- 1..300, do: Neptunus.PubSub.broadcast(topic, "telemetry", Map.put(sample, "k", k))
    telemetry!(ws, topic, 300)

    info = Process.info(pid, :garbage_collection_info) |> elem(1)
    assert info[:old_heap_size] == 0, inspect(info)
  end

  test "an idle connection hibernates, and serves again on the next message", %{topic: topic} do
    # joined to nothing yet: nothing reaches it
    {ws, pid} = connect!("Idle")

    Neptunus.Test.Pty.wait_until(
      fn ->
        Process.info(pid, :current_function) == {:current_function, {:erlang, :hibernate, 3}}
      end,
      "the idle connection to hibernate"
    )

    {:total_heap_size, words} = Process.info(pid, :total_heap_size)
    assert words < 2_500, "hibernated heap #{words} words"

    join!(ws, topic)
    Neptunus.PubSub.broadcast(topic, "telemetry", %{"k" => 7})
    telemetry!(ws, topic, 7)
    WSClient.push(ws, nil, "hb", "phoenix", "heartbeat", %{})

    assert [nil, "hb", "phoenix", "phx_reply", %{"status" => "ok"}] =
             WSClient.recv_until(ws, &match?([_, "hb", _, _, _], &1))
  end

  test "a streaming connection hibernates at each idle check (its heap shrinks to its live data)",
       %{topic: topic} do
    {ws, pid} = connect!("Shrink")
    join!(ws, topic)

    assert [_, _, ^topic, "telemetry", _] =
             WSClient.recv_until(ws, &match?([_, _, _, "telemetry", _], &1))

    # the vehicle's telemetry streams at 20 Hz: the connection is never idle for a second, and
    # is scheduled out in hibernation only when the idle check hibernates it
    :erlang.trace(pid, true, [:running])
    send(pid, :check_idle)
    assert_receive {:trace, ^pid, :out, {:erlang, :hibernate, 3}}
    :erlang.trace(pid, false, [:running])

    # and it streams on
    WSClient.recv_until(ws, &match?([_, _, _, "telemetry", _], &1))
    WSClient.recv_until(ws, &match?([_, _, _, "telemetry", _], &1))
  end
end
