defmodule NeptunusWeb.FdLimitTest do
  # Boots a node in its own OS process with a soft descriptor limit of 256 (`ulimit -Sn`, as a
  # service gets 1024), and from this VM, while a pilot drives its vehicle, opens twice as many
  # idle TCP connections as the node serves at once, plus one that trickles its headers. The
  # pilot must never notice; the endpoint must not restart; the connections beyond the limit
  # are closed at once, the idle ones within the header timeout; afterwards the node serves
  # new clients.
  use ExUnit.Case, async: false

  import Neptunus.Test.Vehicles, only: [free_port: 0]

  alias Neptunus.Test.Patience
  alias NeptunusWeb.Test.WSClient

  @moduletag :boot
  @moduletag timeout: 120_000
  @root Path.expand("../..", __DIR__)
  @soft_limit 256
  @vehicle "fd-rov"

  # Runs in the node: reports its limits and the endpoint's processes, then answers "report"
  # lines on its input until the input closes.
  @node_script ~S"""
  endpoint = Process.whereis(NeptunusWeb.Endpoint)
  yaws = Process.whereis(:yaws_server)
  # yaws' listener processes (which hold the acceptor and every connection)
  listeners = fn ->
    {:links, links} = Process.info(Process.whereis(:yaws_server), :links)
    for pid <- links, is_pid(pid),
        {:dictionary, d} = Process.info(pid, :dictionary),
        match?({:yaws_server, _, _}, d[:"$initial_call"]), do: pid
  end
  listening = listeners.()
  [_ | _] = listening
  {:ok, {soft, hard}} = Neptunus.OS.fd_limit()
  {:ok, gc, _} = :yaws_api.getconf()
  IO.puts("READY max_connections=#{elem(gc, 13)} soft=#{soft} hard=#{hard} " <>
    "sockets=#{Neptunus.OS.socket_limit()} header_timeout=#{NeptunusWeb.Endpoint.header_timeout_ms()}")
  loop = fn loop ->
    case IO.read(:stdio, :line) do
      "report\n" ->
        # what the connection log counted so far, logged now
        NeptunusWeb.Endpoint.ConnectionLog.flush()
        same = Process.whereis(NeptunusWeb.Endpoint) == endpoint and
          Process.whereis(:yaws_server) == yaws and listeners.() == listening
        IO.puts("REPORT same_endpoint=#{same}")
        loop.(loop)
      _ -> :ok
    end
  end
  loop.(loop)
  """

  setup do
    mix = System.find_executable("mix") || flunk("mix not found")
    sh = System.find_executable("sh") || flunk("sh not found")
    port_number = free_port()

    env =
      for(
        var <- ~w(NEPTUNUS_SECRET NEPTUNUS_USERS NEPTUNUS_USERS_FILE NEPTUNUS_BIND
                  NEPTUNUS_TLS_CERT NEPTUNUS_TLS_KEY NEPTUNUS_MAX_CONNECTIONS),
        do: {String.to_charlist(var), false}
      ) ++
        [
          {~c"MIX_ENV", ~c"test"},
          {~c"NEPTUNUS_PORT", Integer.to_charlist(port_number)},
          {~c"NEPTUNUS_VEHICLES", ~c"#{@vehicle}=simulated"},
          {~c"NEPTUNUS_RECORDINGS", ~c"off"},
          # what is tested is the pilot's socket and control: a machine loaded by other work
          # (the flood's client runs here too) must not trip the deadman meanwhile
          {~c"NEPTUNUS_DEADMAN_MS", ~c"10000"}
        ]

    node =
      Port.open({:spawn_executable, sh}, [
        :binary,
        :exit_status,
        :stderr_to_stdout,
        {:line, 4096},
        {:cd, @root},
        {:env, env},
        {:args,
         [
           "-c",
           "ulimit -Sn #{@soft_limit} && exec \"$0\" run --no-compile -e \"$1\"",
           mix,
           @node_script
         ]}
      ])

    on_exit(fn -> if Port.info(node), do: Port.close(node) end)

    ready = await_line(node, "READY ", 60_000)
    [limit, soft, hard, sockets, timeout] = numbers(ready)

    {:ok,
     node: node,
     port: port_number,
     limit: limit,
     timeout: timeout,
     soft: soft,
     hard: hard,
     sockets: sockets}
  end

  test "twice the connection limit of idle connections never touches the pilot", ctx do
    # the node raised its soft limit; its sockets stay within the limit it started with
    assert ctx.sockets == @soft_limit
    assert ctx.soft == ctx.hard
    assert ctx.limit < @soft_limit

    test = self()
    driver = spawn_link(fn -> drive(test, ctx.port) end)
    assert_receive {:driving, epoch}

    # the flood: twice the limit, and more than the node's descriptors, nothing sent (this
    # VM's own limit must hold them)
    {:ok, {own_soft, _}} = Neptunus.OS.fd_limit()
    flood = max(2 * ctx.limit, @soft_limit + 64)
    assert own_soft > flood + 200

    # a client trickling its headers, connected before the flood
    trickler = spawn_link(fn -> trickle(test, ctx.port) end)
    assert_receive :trickling

    started = System.monotonic_time(:millisecond)
    sockets = for _ <- 1..flood, do: idle_connect(ctx.port)

    # every flood connection is closed by the node: those beyond the limit at once, the
    # others when the header timeout passes. Waits generously; records when each closed.
    closed_after =
      sockets
      |> Task.async_stream(fn s -> await_close(s, started) end,
        max_concurrency: flood,
        timeout: 30_000
      )
      |> Enum.map(fn {:ok, ms} -> ms end)

    assert Enum.all?(closed_after, &is_integer/1), "a flood connection was never closed"

    # meanwhile the pilot was never stopped nor cut off, and the endpoint never restarted
    send(driver, {:status, self()})
    assert_receive {:driving, ^epoch, :ok}
    Port.command(ctx.node, "report\n")
    assert await_line(ctx.node, "REPORT ", 10_000) =~ "same_endpoint=true"

    # the log says how many were closed beyond the limit (refused at once, not left to the
    # header timeout), in a line now and then, not one line per connection
    refused = refused_in_log(ctx.node, flood - ctx.limit)
    assert refused >= flood - ctx.limit, "only #{refused} of #{flood} refused"
    refute Enum.any?(drain(ctx.node), &(&1 =~ "Max connections reached"))

    # the trickler, who sends a header line every 300 ms, is cut off too
    assert_receive {:trickle_closed, lines}, 30_000
    assert lines in 3..99

    # the node serves new connections again: an HTTP request, a new client joining
    assert {:ok, "HTTP/1.1 200" <> _} = http_get(ctx.port, "/api/health")
    {:ok, ws} = WSClient.connect(ctx.port, "/socket/websocket?vsn=2.0.0&name=Late")
    assert {:ok, _} = WSClient.join(ws, "vehicle:" <> @vehicle)
    WSClient.close(ws)

    # the pilot drove throughout, was never stopped and still holds control with its epoch
    send(driver, {:finish, self()})
    assert_receive {:driven, ^epoch, result}
    assert result == :ok

    # and the endpoint never restarted
    Port.command(ctx.node, "report\n")
    assert await_line(ctx.node, "REPORT ", 10_000) =~ "same_endpoint=true"
    _ = trickler
  end

  # The pilot: joins, takes control and sends thrust and a heartbeat every 50 ms; any
  # `stopped`, lost control or closed socket is the failure it reports when asked.
  defp drive(test, port) do
    Process.flag(:priority, :high)
    {:ok, ws} = WSClient.connect(port, "/socket/websocket?vsn=2.0.0&name=Pilot")
    topic = "vehicle:" <> @vehicle
    jr = WSClient.unique_ref()
    {:ok, _} = WSClient.join(ws, topic, %{}, jr)
    ref = WSClient.unique_ref()
    :ok = WSClient.push(ws, jr, ref, topic, "request_control", %{})

    [_, _, _, _, %{"status" => "ok", "response" => %{"grant" => %{"epoch" => epoch}}}] =
      WSClient.recv_until(ws, &match?([_, ^ref, _, "phx_reply", _], &1))

    send(test, {:driving, epoch})
    drive_loop(ws, jr, topic, epoch, :ok)
  end

  defp drive_loop(ws, jr, topic, epoch, result) do
    receive do
      {:status, from} ->
        send(from, {:driving, epoch, result})
        drive_loop(ws, jr, topic, epoch, result)

      {:finish, from} ->
        ref = WSClient.unique_ref()
        thrust = %{"mode" => "motion", "surge" => 0.2, "heave" => 0, "yaw" => 0, "epoch" => epoch}
        WSClient.push(ws, jr, ref, topic, "thrust", thrust)
        send(from, {:driven, epoch, await_final(ws, ref, result)})

      {:ws, ^ws, {:text, text}} ->
        case :jiffy.decode(text, [:return_maps]) do
          [_, _, _, "stopped", payload] when result == :ok ->
            drive_loop(ws, jr, topic, epoch, {:error, {:stopped, payload}})

          [_, _, _, "phx_reply", %{"status" => "error", "response" => response}]
          when result == :ok ->
            drive_loop(ws, jr, topic, epoch, {:error, {:refused, response}})

          _ ->
            drive_loop(ws, jr, topic, epoch, result)
        end

      {:ws, ^ws, other} ->
        drive_loop(ws, jr, topic, epoch, if(result == :ok, do: {:error, other}, else: result))
    after
      50 ->
        thrust = %{"mode" => "motion", "surge" => 0.3, "heave" => 0, "yaw" => 0, "epoch" => epoch}
        WSClient.push(ws, jr, WSClient.unique_ref(), topic, "thrust", thrust)
        WSClient.push(ws, jr, WSClient.unique_ref(), topic, "heartbeat", %{})
        drive_loop(ws, jr, topic, epoch, result)
    end
  end

  defp await_final(ws, ref, result) do
    receive do
      {:ws, ^ws, {:text, text}} ->
        case :jiffy.decode(text, [:return_maps]) do
          [_, ^ref, _, "phx_reply", %{"status" => "ok"}] -> result
          [_, ^ref, _, "phx_reply", reply] -> {:error, {:final, reply}}
          [_, _, _, "stopped", payload] -> {:error, {:stopped, payload}}
          _ -> await_final(ws, ref, result)
        end

      {:ws, ^ws, other} ->
        {:error, other}
    after
      Patience.ms() -> {:error, :no_final_reply}
    end
  end

  # A client sending a request line, then a short header line every 300 ms (each line well
  # within any per-read timeout) for up to a minute; reports how many lines it sent.
  defp trickle(test, port) do
    {:ok, s} = :gen_tcp.connect(~c"127.0.0.1", port, [:binary, active: false])
    :ok = :gen_tcp.send(s, "GET /api/health HTTP/1.1\r\n")
    send(test, :trickling)
    send(test, {:trickle_closed, trickle_lines(s, 0)})
  end

  defp trickle_lines(_s, 200), do: 200

  defp trickle_lines(s, n) do
    Process.sleep(300)

    with :ok <- :gen_tcp.send(s, "X-#{n}: 1\r\n"),
         {:error, :timeout} <- :gen_tcp.recv(s, 0, 0) do
      trickle_lines(s, n + 1)
    else
      _ -> n
    end
  end

  # a connection the node did not even accept (its listener gone) counts as closed at once
  defp idle_connect(port) do
    case :gen_tcp.connect(~c"127.0.0.1", port, [:binary, active: false], 5_000) do
      {:ok, s} -> s
      {:error, _} -> nil
    end
  end

  # ms after `started` when the node closed `s` (nil: still open after 25 s)
  defp await_close(nil, started), do: System.monotonic_time(:millisecond) - started

  defp await_close(s, started) do
    result = :gen_tcp.recv(s, 0, 25_000)
    :gen_tcp.close(s)

    case result do
      {:error, :timeout} -> nil
      _ -> System.monotonic_time(:millisecond) - started
    end
  end

  defp http_get(port, path) do
    {:ok, s} = :gen_tcp.connect(~c"127.0.0.1", port, [:binary, active: false], 5_000)
    :ok = :gen_tcp.send(s, "GET #{path} HTTP/1.1\r\nHost: 127.0.0.1:#{port}\r\n\r\n")
    result = :gen_tcp.recv(s, 0, Patience.ms())
    :gen_tcp.close(s)
    result
  end

  defp await_line(node, prefix, timeout) do
    receive do
      {^node, {:data, {:eol, line}}} ->
        # the test process keeps the node's output, for checks on its log
        Process.put(:node_output, [line | Process.get(:node_output, [])])
        if String.starts_with?(line, prefix), do: line, else: await_line(node, prefix, timeout)

      {^node, {:data, {:noeol, _}}} ->
        await_line(node, prefix, timeout)

      {^node, {:exit_status, status}} ->
        flunk(
          "the node exited (#{status}) before printing #{prefix}; its last lines:\n#{last_lines()}"
        )
    after
      timeout ->
        flunk(
          "the node printed no #{prefix} within #{timeout} ms; its last lines:\n#{last_lines()}"
        )
    end
  end

  defp last_lines,
    do: Process.get(:node_output, []) |> Enum.take(40) |> Enum.reverse() |> Enum.join("\n")

  # The connections the node's log says it closed beyond the connection limit, in every
  # line of its output so far and still to come, once they reach `wanted` (or what they came
  # to when the node logs no more; the report before sent "report", which flushes the count).
  defp refused_in_log(node, wanted) do
    refused =
      Process.get(:node_output, [])
      |> Enum.flat_map(
        &Regex.scan(~r/closed \d+ connections: (\d+) beyond the connection limit/, &1)
      )
      |> Enum.map(fn [_, n] -> String.to_integer(n) end)
      |> Enum.sum()

    if refused >= wanted do
      refused
    else
      receive do
        {^node, {:data, {:eol, line}}} ->
          Process.put(:node_output, [line | Process.get(:node_output, [])])
          refused_in_log(node, wanted)
      after
        Patience.ms() -> refused
      end
    end
  end

  # the node's output so far
  defp drain(node) do
    receive do
      {^node, {:data, {:eol, line}}} ->
        Process.put(:node_output, [line | Process.get(:node_output, [])])
        drain(node)
    after
      0 -> Enum.reverse(Process.get(:node_output, []))
    end
  end

  defp numbers(line) do
    ~r/=(\d+)/ |> Regex.scan(line) |> Enum.map(fn [_, n] -> String.to_integer(n) end)
  end
end
