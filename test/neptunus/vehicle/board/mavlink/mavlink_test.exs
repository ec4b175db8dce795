defmodule Neptunus.Vehicle.Board.MAVLinkTest do
  # The board process against the test process standing in for the vehicle (UDP and TCP).
  use ExUnit.Case, async: true

  alias Neptunus.Protocol.MAVLink, as: Codec
  alias Neptunus.PubSub
  alias Neptunus.Test.Patience
  alias Neptunus.Vehicle.{Board, Telemetry}

  @vehicle %{system: 1, component: 1}

  setup do
    id = "mav-#{System.unique_integer([:positive])}"
    {:ok, socket} = :gen_udp.open(0, [:binary, active: true, ip: {127, 0, 0, 1}])
    {:ok, port} = :inet.port(socket)
    %{id: id, socket: socket, port: port}
  end

  defp start_board(ctx, opts \\ []) do
    opts = Keyword.merge([id: ctx.id, link: {:udpout, "127.0.0.1", ctx.port}], opts)
    start_supervised!({Board.MAVLink, opts})
  end

  defp frame(name, fields, seq) do
    {:ok, frame} = Codec.encode(name, fields, Map.put(@vehicle, :seq, seq))
    frame
  end

  defp heartbeat(armed \\ false, seq \\ 0) do
    frame(
      :heartbeat,
      %{
        type: 12,
        autopilot: 3,
        base_mode: if(armed, do: 209, else: 81),
        custom_mode: 19,
        system_status: 4
      },
      seq
    )
  end

  # the next message `name` from the board (other messages skipped), with its source
  defp next(name, timeout \\ Patience.ms()),
    do: next_or_nil(name, timeout) || flunk("no #{name} from the board in time")

  defp next_or_nil(name, timeout),
    do: next_until(name, System.monotonic_time(:millisecond) + timeout)

  defp next_until(name, deadline) do
    receive do
      {:udp, _socket, ip, port, data} ->
        {_, messages, _} = Codec.decode(Codec.new(), data)

        case Enum.find(messages, &(&1.name == name)) do
          nil -> next_until(name, deadline)
          m -> {m, {ip, port}}
        end
    after
      max(0, deadline - System.monotonic_time(:millisecond)) -> nil
    end
  end

  defp first_non_neutral do
    case next(:manual_control) do
      {%{fields: %{x: 0, z: 500, r: 0}}, _} -> first_non_neutral()
      {m, _} -> m
    end
  end

  defp vehicle_says(ctx, from, bytes), do: :ok = :gen_udp.send(ctx.socket, from, bytes)

  defp up(ctx) do
    {_, {ip, port}} = next(:heartbeat)
    vehicle_says(ctx, {ip, port}, heartbeat())
    {ip, port}
  end

  test "a ground station: heartbeat as GCS 255/190, streams requested, neutral MANUAL_CONTROL",
       ctx do
    start_board(ctx)
    {hb, from} = next(:heartbeat)
    assert %{system: 255, component: 190, fields: %{type: 6}} = hb
    vehicle_says(ctx, from, heartbeat())
    {req, _} = next(:request_data_stream)
    assert %{target_system: 1, start_stop: 1} = req.fields
    {mc, _} = next(:manual_control)
    assert %{target: 1, x: 0, y: 0, z: 500, r: 0, buttons: 0} = mc.fields

    assert %{up: true, mavlink: %{armed: false, mode: "MANUAL"}} =
             Board.MAVLink.link_status(ctx.id)
  end

  test "our ids are settable", ctx do
    start_board(ctx, system: 254, component: 191)
    assert {%{system: 254, component: 191}, _} = next(:heartbeat)
  end

  test "go becomes MANUAL_CONTROL at once", ctx do
    start_board(ctx)
    up(ctx)
    next(:manual_control)
    Board.go(ctx.id, %{surge: 0.5, sway: -0.25, heave: -0.2, yaw: 0.0})
    # neutral ones sent before the command was handled may come first; the first other one
    # is the command
    assert %{x: 500, y: -250, z: 600, r: 0} = first_non_neutral().fields
  end

  test "arm: the vehicle's ACK answers; a refusal gives its STATUSTEXT", ctx do
    start_board(ctx)
    from = up(ctx)
    next(:request_data_stream)
    me = self()
    assert :ok = Board.MAVLink.arm(ctx.id, true, &send(me, {:armed, &1}))
    {cmd, _} = next(:command_long)
    assert %{command: 400, param1: 1.0, target_system: 1} = cmd.fields
    vehicle_says(ctx, from, frame(:statustext, %{severity: 2, text: "Arm: Leak detected"}, 1))
    vehicle_says(ctx, from, frame(:command_ack, %{command: 400, result: 4}, 2))
    assert_receive {:armed, {:error, "Arm: Leak detected"}}

    assert :ok = Board.MAVLink.arm(ctx.id, true, &send(me, {:armed, &1}))
    next(:command_long)
    vehicle_says(ctx, from, frame(:command_ack, %{command: 400, result: 0}, 3))
    assert_receive {:armed, :ok}
  end

  test "arming is refused at once while the link is down", ctx do
    start_board(ctx)
    me = self()
    assert :ok = Board.MAVLink.arm(ctx.id, true, &send(me, {:armed, &1}))
    assert_receive {:armed, {:error, "the vehicle's link is down" <> _}}
  end

  test "a pilot-loss stop disarms after the delay", ctx do
    start_board(ctx, disarm_delay: 0.2)
    from = up(ctx)
    vehicle_says(ctx, from, heartbeat(true, 1))
    # the board reports the armed vehicle
    wait_until(fn -> Board.MAVLink.link_status(ctx.id).mavlink.armed end)
    PubSub.broadcast(Telemetry.topic(ctx.id), "stopped", %{reason: "pilot_disconnected"})
    {cmd, _} = next(:command_long)
    assert %{command: 400, param1: +0.0} = cmd.fields
  end

  test "the same pilot in a changed helm party does not cancel the disarm; a new one does", ctx do
    start_board(ctx, disarm_delay: 0.3)
    from = up(ctx)
    vehicle_says(ctx, from, heartbeat(true, 1))
    wait_until(fn -> Board.MAVLink.link_status(ctx.id).mavlink.armed end)
    topic = Telemetry.topic(ctx.id)
    ada = %{id: "c1", name: "Ada", role: "pilot", since: 1}
    PubSub.broadcast(topic, "helm", %{pilot: ada})
    PubSub.broadcast(topic, "stopped", %{reason: "deadman"})
    PubSub.broadcast(topic, "helm", %{pilot: %{ada | since: 2}})
    {cmd, _} = next(:command_long)
    assert %{command: 400, param1: +0.0} = cmd.fields

    PubSub.broadcast(topic, "stopped", %{reason: "pilot_disconnected"})
    PubSub.broadcast(topic, "helm", %{pilot: nil})
    PubSub.broadcast(topic, "helm", %{pilot: %{id: "c2", name: "Bob", role: "pilot", since: 3}})
    wait_until(fn -> not Board.MAVLink.link_status(ctx.id).mavlink.disarm_pending end)
  end

  test "STATUSTEXT goes to the vehicle's log with its severity", ctx do
    :ok = PubSub.subscribe(Telemetry.log_topic(ctx.id))
    start_board(ctx)
    from = up(ctx)
    vehicle_says(ctx, from, frame(:statustext, %{severity: 4, text: "Leak!"}, 1))

    assert_receive {:pubsub, _, "log",
                    %{category: "vehicle", level: "warning", message: "Leak!", severity: 4}}
  end

  test "frames lost are counted from the vehicle's sequence numbers", ctx do
    start_board(ctx)
    from = up(ctx)
    vehicle_says(ctx, from, heartbeat(false, 5))
    wait_until(fn -> Board.MAVLink.link_status(ctx.id).frames.lost == 4 end)
  end

  test "telemetry's link carries the vehicle's state and the frame loss", ctx do
    # the test process stands in for the vehicle's telemetry: it gets the board's link reports
    {:ok, _} = Registry.register(Neptunus.Fleet.Registry, {Telemetry, ctx.id}, nil)
    start_board(ctx)
    from = up(ctx)
    vehicle_says(ctx, from, heartbeat(true, 3))
    link_report!(&match?(%{mavlink: %{armed: true, frames_lost: 2, frames_received: 2}}, &1))

    assert %{up: true, reason: "heartbeat", mavlink: %{loss: 0.5, mode: "MANUAL"}} =
             link_report!(&(&1.mavlink.loss > 0))
  end

  test "udp: listens and answers whoever sent last", ctx do
    {:ok, probe} = :gen_udp.open(0, [:binary, ip: {127, 0, 0, 1}])
    {:ok, free} = :inet.port(probe)
    :gen_udp.close(probe)
    start_board(ctx, link: {:udp, {127, 0, 0, 1}, free})
    # the board opens its socket after it has started: like a vehicle, the test says its
    # heartbeat again (every 250 ms here) until the board answers
    deadline = System.monotonic_time(:millisecond) + Patience.ms()

    assert {%{fields: %{type: 6}}, _} =
             Stream.repeatedly(fn ->
               vehicle_says(ctx, {{127, 0, 0, 1}, free}, heartbeat())
               next_or_nil(:heartbeat, 250)
             end)
             |> Stream.take_while(fn _ -> System.monotonic_time(:millisecond) < deadline end)
             |> Enum.find(& &1) || flunk("no heartbeat from the board in time")
  end

  test "tcp: connects, and reconnects after the vehicle closes", ctx do
    {:ok, listen} = :gen_tcp.listen(0, [:binary, active: true, ip: {127, 0, 0, 1}])
    {:ok, port} = :inet.port(listen)
    start_board(ctx, link: {:tcp, "127.0.0.1", port}, reconnect_ms: 50)
    {:ok, conn} = :gen_tcp.accept(listen, Patience.ms())
    assert_receive {:tcp, ^conn, data}
    {_, [first | _], _} = Codec.decode(Codec.new(), data)
    assert first.name == :heartbeat
    :gen_tcp.close(conn)
    {:ok, conn2} = :gen_tcp.accept(listen, Patience.ms())
    :ok = :gen_tcp.send(conn2, heartbeat())
    wait_until(fn -> Board.MAVLink.link_status(ctx.id).up end)
  end

  defp link_report!(pred) do
    receive do
      {:"$gen_cast", {:link, link}} -> if pred.(link), do: link, else: link_report!(pred)
    after
      Patience.ms() -> flunk("no such link report")
    end
  end

  defp wait_until(fun), do: Neptunus.Test.Pty.wait_until(fun, "the condition")
end

defmodule Neptunus.Vehicle.Board.MAVLinkSerialTest do
  # The serial link through our port program, on a socat pty pair: the test is the vehicle on
  # one end (`Pty.open!/1`), the board opens the other.
  use ExUnit.Case, async: true

  alias Neptunus.Protocol.MAVLink, as: Codec
  alias Neptunus.Test.{Patience, Pty}
  alias Neptunus.Vehicle.Board

  defp next(port, name),
    do: next(port, name, Codec.new(), System.monotonic_time(:millisecond) + Patience.ms())

  defp next(port, name, decoder, deadline) do
    receive do
      {^port, {:data, "r" <> data}} ->
        {decoder, messages, _} = Codec.decode(decoder, data)

        case Enum.find(messages, &(&1.name == name)) do
          nil -> next(port, name, decoder, deadline)
          m -> m
        end

      {^port, {:data, _}} ->
        next(port, name, decoder, deadline)
    after
      max(0, deadline - System.monotonic_time(:millisecond)) ->
        flunk("no #{name} on the serial line")
    end
  end

  test "serial: heartbeat and MANUAL_CONTROL over the line; the vehicle's heartbeat brings the link up" do
    pair = Pty.socat_pair!()
    vehicle = Pty.open!(pair.a)
    id = "mav-serial-#{System.unique_integer([:positive])}"
    start_supervised!({Board.MAVLink, id: id, link: {:serial, pair.b, 115_200}})
    assert %{system: 255, fields: %{type: 6}} = next(vehicle, :heartbeat)

    {:ok, hb} =
      Codec.encode(
        :heartbeat,
        %{type: 12, autopilot: 3, base_mode: 81, custom_mode: 19, system_status: 3},
        %{system: 1, component: 1, seq: 0}
      )

    Pty.write(vehicle, hb)
    assert %{fields: %{x: 0, z: 500, target: 1}} = next(vehicle, :manual_control)
    Pty.wait_until(fn -> Board.MAVLink.link_status(id).up end, "the link up")
    assert Board.MAVLink.link_status(id).transport == "serial open"
  end

  test "serial: its port closed without an exit status (a write that found the program gone) is reopened" do
    pair = Pty.socat_pair!()
    _vehicle = Pty.open!(pair.a)
    id = "mav-serial-#{System.unique_integer([:positive])}"
    start_supervised!({Board.MAVLink, id: id, link: {:serial, pair.b, 115_200}, reconnect_ms: 50})
    Pty.wait_until(fn -> Board.MAVLink.link_status(id).transport == "serial open" end, "open")

    # the port ends with only its exit signal, as when a write fails (epipe) before the
    # program's exit status reached the VM
    Port.close(:sys.get_state(Board.via(id)).socket)

    Pty.wait_until(
      fn -> Board.MAVLink.link_status(id).counters.opens >= 2 end,
      "a second open"
    )
  end

  test "serial: a device that cannot be opened is retried, and said why" do
    id = "mav-serial-#{System.unique_integer([:positive])}"

    start_supervised!(
      {Board.MAVLink, id: id, link: {:serial, "/nonexistent/tty", 115_200}, reconnect_ms: 50}
    )

    Pty.wait_until(
      fn -> Board.MAVLink.link_status(id).counters.opens >= 2 end,
      "a second open"
    )

    refute Board.MAVLink.link_status(id).up
  end
end
