defmodule NeptunusWeb.Test.WSClientTest do
  use ExUnit.Case, async: true

  alias Neptunus.Test.Patience
  alias NeptunusWeb.Test.WSClient

  @guid "258EAFA5-E914-47DA-95CA-C5AB0DC85B11"

  # A tiny WebSocket server on :gen_tcp, independent of the client's code.
  # It reports every client frame to the test as
  # {:server, {:frame, fin, opcode, masked, payload}} and, in :echo mode,
  # echoes text/binary, answers close, and obeys a few text commands.

  defp messages, do: elem(Process.info(self(), :messages), 1)

  defp start_server(mode) do
    test = self()
    {:ok, listen} = :gen_tcp.listen(0, [:binary, active: false, packet: :raw])
    {:ok, port} = :inet.port(listen)
    spawn_link(fn -> serve(listen, mode, test) end)
    port
  end

  defp serve(listen, mode, test) do
    {:ok, sock} = :gen_tcp.accept(listen, Patience.ms())
    request = read_request(sock, "")
    send(test, {:server, {:request, request}})
    [_, key] = Regex.run(~r/sec-websocket-key:\s*(\S+)/i, request)
    accept = Base.encode64(:crypto.hash(:sha, key <> @guid))

    case mode do
      :forbidden ->
        :gen_tcp.send(sock, "HTTP/1.1 403 Forbidden\r\nContent-Length: 9\r\n\r\nforbidden")

      :bad_accept ->
        :gen_tcp.send(sock, upgrade_response("d3Jvbmc="))

      :echo ->
        # the first frame rides in the same TCP segment as the 101
        :gen_tcp.send(sock, [upgrade_response(accept), out(1, "hello")])
        loop(sock, test)
    end

    Process.sleep(:infinity)
  end

  defp upgrade_response(accept) do
    "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n" <>
      "Sec-WebSocket-Accept: #{accept}\r\n\r\n"
  end

  defp read_request(sock, acc) do
    if String.ends_with?(acc, "\r\n\r\n") do
      acc
    else
      {:ok, data} = :gen_tcp.recv(sock, 0, Patience.ms())
      read_request(sock, acc <> data)
    end
  end

  defp loop(sock, test) do
    case read_frame(sock) do
      :closed ->
        send(test, {:server, :tcp_closed})

      {fin, opcode, masked, payload} ->
        send(test, {:server, {:frame, fin, opcode, masked, payload}})
        if act(sock, opcode, payload) == :continue, do: loop(sock, test)
    end
  end

  defp act(sock, 8, payload) do
    :gen_tcp.send(sock, out(8, payload))
    :gen_tcp.close(sock)
  end

  defp act(sock, 1, "drop"), do: :gen_tcp.close(sock)

  defp act(sock, 1, "close_me") do
    :gen_tcp.send(sock, out(8, <<1001::16, "bye">>))
    :continue
  end

  defp act(sock, 1, "fragments") do
    :gen_tcp.send(sock, [out(1, "ab", 0), out(9, "p1"), out(0, "cd", 0), out(0, "ef")])
    :continue
  end

  defp act(sock, 1, "masked") do
    :gen_tcp.send(sock, <<1::1, 0::3, 1::4, 1::1, 1::7, 0::32, "x">>)
    :continue
  end

  defp act(sock, 1, text) do
    reply =
      case :jiffy.decode(text, [:return_maps, {:null_term, nil}]) do
        [jr, ref, topic, "phx_join", params] ->
          status = if params["deny"], do: "error", else: "ok"
          noise = :jiffy.encode([nil, nil, topic, "telemetry", %{}], [:use_nil])
          reply = [jr, ref, topic, "phx_reply", %{status: status, response: params}]
          [out(1, noise), out(1, :jiffy.encode(reply, [:use_nil]))]

        _ ->
          out(1, text)
      end

    :gen_tcp.send(sock, reply)
    :continue
  catch
    _, _ ->
      :gen_tcp.send(sock, out(1, text))
      :continue
  end

  defp act(sock, 2, payload) do
    :gen_tcp.send(sock, out(2, payload))
    :continue
  end

  defp act(_sock, _opcode, _payload), do: :continue

  defp read_frame(sock) do
    with {:ok, <<fin::1, _::3, opcode::4, masked::1, len::7>>} <- :gen_tcp.recv(sock, 2),
         {:ok, len} <- read_length(sock, len),
         {:ok, key} <- if(masked == 1, do: :gen_tcp.recv(sock, 4), else: {:ok, <<0::32>>}),
         {:ok, payload} <- if(len == 0, do: {:ok, ""}, else: :gen_tcp.recv(sock, len)) do
      keystream = key |> :binary.copy(div(len, 4) + 1) |> binary_part(0, len)
      {fin, opcode, masked, :crypto.exor(payload, keystream)}
    else
      _ -> :closed
    end
  end

  defp read_length(sock, 126), do: with({:ok, <<n::16>>} <- :gen_tcp.recv(sock, 2), do: {:ok, n})
  defp read_length(sock, 127), do: with({:ok, <<n::64>>} <- :gen_tcp.recv(sock, 8), do: {:ok, n})
  defp read_length(_sock, n), do: {:ok, n}

  defp out(opcode, payload, fin \\ 1) do
    payload = IO.iodata_to_binary(payload)
    len = byte_size(payload)

    len_bits =
      cond do
        len < 126 -> <<len::7>>
        len < 65_536 -> <<126::7, len::16>>
        true -> <<127::7, len::64>>
      end

    <<fin::1, 0::3, opcode::4, 0::1, len_bits::bitstring, payload::binary>>
  end

  defp connect_echo(path \\ "/socket/websocket?vsn=2.0.0", opts \\ []) do
    port = start_server(:echo)
    {:ok, ws} = WSClient.connect(port, path, opts)
    assert_receive {:ws, ^ws, {:text, "hello"}}
    ws
  end

  describe "handshake" do
    test "sends a valid upgrade request and receives data following the 101" do
      ws = connect_echo("/socket/websocket?token=abc&vsn=2.0.0", headers: [{"X-Test", "yes"}])
      assert_received {:server, {:request, request}}
      assert request =~ ~r"^GET /socket/websocket\?token=abc&vsn=2\.0\.0 HTTP/1\.1\r\n"
      assert request =~ ~r/\r\nHost: 127\.0\.0\.1:\d+\r\n/
      assert request =~ "\r\nUpgrade: websocket\r\n"
      assert request =~ "\r\nSec-WebSocket-Version: 13\r\n"
      assert request =~ "\r\nX-Test: yes\r\n"
      assert Process.alive?(ws)
    end

    test "non-101 response is an :http_status error with headers and body" do
      port = start_server(:forbidden)

      assert {:error, {:http_status, 403, %{body: "forbidden", headers: headers}}} =
               WSClient.connect(port, "/socket/websocket")

      assert {"content-length", "9"} in headers
    end

    test "wrong Sec-WebSocket-Accept is rejected" do
      port = start_server(:bad_accept)

      assert {:error, {:bad_handshake, "wrong Sec-WebSocket-Accept \"d3Jvbmc=\""}} =
               WSClient.connect(port, "/")
    end

    test "connection refused" do
      {:ok, listen} = :gen_tcp.listen(0, [])
      {:ok, port} = :inet.port(listen)
      :gen_tcp.close(listen)
      assert {:error, :econnrefused} = WSClient.connect(port, "/")
    end
  end

  describe "messages" do
    test "small text round trip, masked on the wire" do
      ws = connect_echo()
      assert :ok = WSClient.send_text(ws, "ping?")
      assert_receive {:server, {:frame, 1, 1, 1, "ping?"}}
      assert_receive {:ws, ^ws, {:text, "ping?"}}
    end

    test "extended payload lengths (16 and 64 bit) both ways" do
      ws = connect_echo()

      for size <- [125, 126, 300, 65_535, 70_000] do
        text = String.duplicate("x", size - 1) <> "!"
        :ok = WSClient.send_text(ws, text)
        assert_receive {:ws, ^ws, {:text, ^text}}
      end
    end

    test "binary round trip" do
      ws = connect_echo()
      bin = :crypto.strong_rand_bytes(1_000)
      :ok = WSClient.send_binary(ws, bin)
      assert_receive {:ws, ^ws, {:binary, ^bin}}
    end

    test "fragmented server message is reassembled and an interleaved ping is answered" do
      ws = connect_echo()
      :ok = WSClient.send_text(ws, "fragments")
      assert_receive {:ws, ^ws, {:text, "abcdef"}}
      assert_receive {:server, {:frame, 1, 10, 1, "p1"}}
    end

    test "raw frames: unmasked and fragmented from the client" do
      ws = connect_echo()
      :ok = WSClient.send_frame(ws, :text, "plain", mask: false)
      assert_receive {:server, {:frame, 1, 1, 0, "plain"}}
      :ok = WSClient.send_frame(ws, :text, "ab", fin: false)
      :ok = WSClient.send_frame(ws, :continuation, "cd")
      assert_receive {:server, {:frame, 0, 1, 1, "ab"}}
      assert_receive {:server, {:frame, 1, 0, 1, "cd"}}
      :ok = WSClient.send_frame(ws, 9, "hi")
      assert_receive {:server, {:frame, 1, 9, 1, "hi"}}
    end

    test "masked frame from the server is a protocol error" do
      ws = connect_echo()
      :ok = WSClient.send_text(ws, "masked")
      assert_receive {:ws, ^ws, {:error, "masked frame from server"}}
      assert_receive {:server, {:frame, 1, 8, 1, <<1002::16>>}}
      assert_receive {:ws, ^ws, :closed}
    end
  end

  describe "closing" do
    test "client-initiated close handshake" do
      ws = connect_echo()
      ref = Process.monitor(ws)
      assert :ok = WSClient.close(ws, 1000, "done")
      assert_receive {:server, {:frame, 1, 8, 1, <<1000::16, "done">>}}
      assert_receive {:ws, ^ws, {:close, 1000, "done"}}
      assert_receive {:ws, ^ws, :closed}
      assert_receive {:DOWN, ^ref, :process, ^ws, :normal}
      assert WSClient.send_text(ws, "late") == {:error, :closed}
    end

    test "server-initiated close is echoed" do
      ws = connect_echo()
      :ok = WSClient.send_text(ws, "close_me")
      assert_receive {:ws, ^ws, {:close, 1001, "bye"}}
      assert_receive {:server, {:frame, 1, 8, 1, <<1001::16>>}}
      assert_receive {:ws, ^ws, :closed}
    end

    test "server-side TCP drop is reported as :closed" do
      ws = connect_echo()
      ref = Process.monitor(ws)
      :ok = WSClient.send_text(ws, "drop")
      assert_receive {:ws, ^ws, :closed}
      assert_receive {:DOWN, ^ref, :process, ^ws, :normal}
      refute_received {:ws, ^ws, {:close, _, _}}
    end

    test "the client exits when its owner does" do
      test = self()
      port = start_server(:echo)

      owner =
        spawn(fn ->
          {:ok, ws} = WSClient.connect(port, "/")
          send(test, {:ws_pid, ws})
          Process.sleep(:infinity)
        end)

      assert_receive {:ws_pid, ws}
      ref = Process.monitor(ws)
      Process.exit(owner, :kill)
      assert_receive {:DOWN, ^ref, :process, ^ws, :normal}
      assert_receive {:server, :tcp_closed}
    end
  end

  describe "channels helpers" do
    test "push and recv_frame" do
      ws = connect_echo()
      :ok = WSClient.push(ws, "1", "2", "vehicle:a", "thrust", %{surge: 0.5, yaw: nil})

      assert WSClient.recv_frame(ws) == [
               "1",
               "2",
               "vehicle:a",
               "thrust",
               %{"surge" => 0.5, "yaw" => nil}
             ]
    end

    test "join skips unrelated frames and returns the reply" do
      ws = connect_echo()
      assert WSClient.join(ws, "vehicle:a", %{"token" => "t"}) == {:ok, %{"token" => "t"}}
      assert WSClient.join(ws, "vehicle:b", %{"deny" => true}, "9") == {:error, %{"deny" => true}}
    end

    test "recv_until returns the first matching frame" do
      ws = connect_echo()
      for i <- 1..3, do: :ok = WSClient.push(ws, nil, "#{i}", "t", "e", %{})
      assert [nil, "3", "t", "e", %{}] = WSClient.recv_until(ws, &match?([_, "3" | _], &1))
    end

    test "timeouts and non-frames fail clearly" do
      ws = connect_echo()

      assert_raise ExUnit.AssertionError, ~r/no frame received within 50 ms/, fn ->
        WSClient.recv_frame(ws, 50)
      end

      :ok = WSClient.push(ws, nil, "1", "t", "e", %{})
      # its echo is in before the wait that must fail on it starts (however slow the machine)
      Neptunus.Test.Pty.wait_until(
        fn -> Enum.any?(messages(), &match?({:ws, ^ws, {:text, _}}, &1)) end,
        "the echo"
      )

      assert_raise ExUnit.AssertionError, ~r/1 frame\(s\) did not match/, fn ->
        WSClient.recv_until(ws, fn _ -> false end, 100)
      end

      :ok = WSClient.send_text(ws, "not json")

      assert_raise ExUnit.AssertionError, ~r/not a Phoenix Channels v2 frame/, fn ->
        WSClient.recv_frame(ws)
      end

      :ok = WSClient.send_text(ws, "drop")
      assert_raise ExUnit.AssertionError, ~r/connection closed/, fn -> WSClient.recv_frame(ws) end
    end
  end
end
