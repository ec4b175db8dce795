defmodule Neptunus.Test.RTSPServer do
  @moduledoc """
  A small RTSP server for tests (RFC 2326, RTP over the RTSP connection, H.264 in RTP per
  RFC 6184): what an IP camera serves, so the `rtsp://` source is tested with ffmpeg as its
  real client. ffmpeg can publish to an RTSP server but not be one a client plays from, hence
  this.

  It serves one stream at `rtsp://127.0.0.1:PORT/stream`: the access units it is given (lists
  of NAL units, the first a keyframe with SPS and PPS) over and over at `fps`, each NAL unit
  in one RTP packet or, when larger than 1 200 bytes, in FU-A fragments; the marker bit on an
  access unit's last packet. It answers OPTIONS, DESCRIBE (an SDP with the SPS and PPS),
  SETUP (only `RTP/AVP/TCP;interleaved=0-1`), PLAY, GET_PARAMETER and TEARDOWN, and ignores
  the client's RTCP. `stop/1` closes it and every connection (a camera that goes away).
  """
  use GenServer

  alias Neptunus.Camera.H264

  @max_packet 1_200

  @doc "Starts serving `aus` (lists of NAL units) at `fps`; `{:ok, pid, port}`."
  @spec start([[binary()]], pos_integer()) :: {:ok, pid(), :inet.port_number()}
  def start(aus, fps) do
    {:ok, pid} = GenServer.start(__MODULE__, {aus, fps})
    {:ok, pid, GenServer.call(pid, :port)}
  end

  @doc "Stops serving: the listener and every connection close."
  @spec stop(pid()) :: :ok
  def stop(pid), do: GenServer.stop(pid)

  @impl true
  def init({aus, fps}) do
    {:ok, listen} =
      :gen_tcp.listen(0, [:binary, active: false, reuseaddr: true, ip: {127, 0, 0, 1}])

    {:ok, port} = :inet.port(listen)
    me = self()
    acceptor = spawn_link(fn -> accept(listen, me, aus, fps) end)
    {:ok, %{listen: listen, port: port, acceptor: acceptor, sessions: []}}
  end

  @impl true
  def handle_call(:port, _from, state), do: {:reply, state.port, state}

  @impl true
  def handle_info({:session, pid}, state),
    do: {:noreply, %{state | sessions: [pid | state.sessions]}}

  def handle_info(_msg, state), do: {:noreply, state}

  @impl true
  def terminate(_reason, state) do
    :gen_tcp.close(state.listen)
    Enum.each(state.sessions, &Process.exit(&1, :kill))
  end

  defp accept(listen, server, aus, fps) do
    case :gen_tcp.accept(listen) do
      {:ok, socket} ->
        pid = spawn(fn -> receive(do: (:go -> session(socket, aus, fps, <<>>))) end)
        :ok = :gen_tcp.controlling_process(socket, pid)
        send(server, {:session, pid})
        send(pid, :go)
        accept(listen, server, aus, fps)

      {:error, _} ->
        :ok
    end
  end

  # Reads requests (and skips interleaved RTCP) until PLAY, then streams while answering.
  defp session(socket, aus, fps, buffer) do
    case next_request(socket, buffer) do
      {:ok, request, rest} ->
        case answer(socket, request, aus) do
          :play ->
            :inet.setopts(socket, active: true)
            stream(socket, aus, fps, 0, rest)

          :ok ->
            session(socket, aus, fps, rest)
        end

      :closed ->
        :ok
    end
  end

  defp next_request(socket, buffer) do
    case parse(buffer) do
      {:request, request, rest} ->
        {:ok, request, rest}

      {:skip, rest} ->
        next_request(socket, rest)

      :more ->
        case :gen_tcp.recv(socket, 0) do
          {:ok, data} -> next_request(socket, buffer <> data)
          {:error, _} -> :closed
        end
    end
  end

  # an interleaved packet from the client (RTCP), or a request whose head is complete
  defp parse(<<?$, _channel, len::16, _::binary-size(len), rest::binary>>), do: {:skip, rest}
  defp parse(<<?$, _::binary>>), do: :more

  defp parse(buffer) do
    case :binary.split(buffer, "\r\n\r\n") do
      [head, rest] ->
        [line | headers] = String.split(head, "\r\n")

        headers =
          Map.new(headers, fn h ->
            [k, v] = String.split(h, ":", parts: 2)
            {String.downcase(String.trim(k)), String.trim(v)}
          end)

        [method | _] = String.split(line, " ")
        {:request, %{method: method, headers: headers}, rest}

      [_] ->
        :more
    end
  end

  defp answer(socket, %{method: method, headers: headers}, aus) do
    cseq = Map.get(headers, "cseq", "0")

    case method do
      "OPTIONS" ->
        reply(socket, cseq, ["Public: OPTIONS, DESCRIBE, SETUP, PLAY, GET_PARAMETER, TEARDOWN"])

      "DESCRIBE" ->
        {:ok, port} = :inet.port(socket)
        sdp = sdp(aus)

        reply(
          socket,
          cseq,
          [
            "Content-Base: rtsp://127.0.0.1:#{port}/stream/",
            "Content-Type: application/sdp",
            "Content-Length: #{byte_size(sdp)}"
          ],
          sdp
        )

      "SETUP" ->
        reply(socket, cseq, [
          "Transport: RTP/AVP/TCP;unicast;interleaved=0-1",
          "Session: 47112344;timeout=60"
        ])

      "PLAY" ->
        reply(socket, cseq, ["Session: 47112344", "Range: npt=0.000-"])
        :play

      _ ->
        reply(socket, cseq, ["Session: 47112344"])
    end
  end

  defp reply(socket, cseq, headers, body \\ "") do
    head = Enum.map(["RTSP/1.0 200 OK", "CSeq: #{cseq}" | headers], &[&1, "\r\n"])
    :gen_tcp.send(socket, [head, "\r\n", body])
    :ok
  end

  defp sdp([first | _]) do
    [sps] = Enum.filter(first, &(H264.type(&1) == 7))
    [pps] = Enum.filter(first, &(H264.type(&1) == 8))
    <<_, profile_level::binary-3, _::binary>> = sps

    Enum.join(
      [
        "v=0",
        "o=- 0 0 IN IP4 127.0.0.1",
        "s=Neptunus test camera",
        "t=0 0",
        "m=video 0 RTP/AVP 96",
        "a=rtpmap:96 H264/90000",
        "a=fmtp:96 packetization-mode=1;profile-level-id=#{Base.encode16(profile_level)};" <>
          "sprop-parameter-sets=#{Base.encode64(sps)},#{Base.encode64(pps)}",
        "a=control:track1",
        ""
      ],
      "\r\n"
    )
  end

  defp stream(socket, aus, fps, n, buffer) do
    au = Enum.at(aus, rem(n, length(aus)))
    timestamp = rem(div(n * 90_000, fps), 0x1_0000_0000)
    packets = packets(au)
    last = length(packets) - 1

    result =
      packets
      |> Enum.with_index()
      |> Enum.reduce_while(:ok, fn {payload, i}, :ok ->
        rtp =
          <<2::2, 0::1, 0::1, 0::4, if(i == last, do: 1, else: 0)::1, 96::7,
            rem(n * 64 + i, 65_536)::16, timestamp::32, 0x4E505455::32, payload::binary>>

        case :gen_tcp.send(socket, [?$, 0, <<byte_size(rtp)::16>>, rtp]) do
          :ok -> {:cont, :ok}
          {:error, _} -> {:halt, :closed}
        end
      end)

    if result == :ok do
      receive do
        {:tcp, ^socket, data} ->
          buffer = answer_all(socket, buffer <> data, aus)
          wait_frame(socket, aus, fps, n, buffer)

        {:tcp_closed, ^socket} ->
          :ok
      after
        div(1000, fps) -> stream(socket, aus, fps, n + 1, buffer)
      end
    end
  end

  defp wait_frame(socket, aus, fps, n, buffer), do: stream(socket, aus, fps, n + 1, buffer)

  # requests while playing (keep-alive GET_PARAMETER, TEARDOWN)
  defp answer_all(socket, buffer, aus) do
    case parse(buffer) do
      {:request, request, rest} ->
        answer(socket, request, aus)
        answer_all(socket, rest, aus)

      {:skip, rest} ->
        answer_all(socket, rest, aus)

      :more ->
        buffer
    end
  end

  # RTP payloads of an access unit (RFC 6184): single NAL unit packets, FU-A for large ones
  defp packets(au), do: Enum.flat_map(au, &nal_packets/1)

  defp nal_packets(nal) when byte_size(nal) <= @max_packet, do: [nal]

  defp nal_packets(<<header, body::binary>>) do
    import Bitwise
    indicator = (header &&& 0xE0) ||| 28
    type = header &&& 0x1F
    chunks = chunk(body, @max_packet - 2)
    last = length(chunks) - 1

    chunks
    |> Enum.with_index()
    |> Enum.map(fn {chunk, i} ->
      s = if i == 0, do: 0x80, else: 0
      e = if i == last, do: 0x40, else: 0
      <<indicator, s ||| e ||| type, chunk::binary>>
    end)
  end

  defp chunk(<<>>, _size), do: []

  defp chunk(bin, size) when byte_size(bin) <= size, do: [bin]

  defp chunk(bin, size) do
    <<part::binary-size(size), rest::binary>> = bin
    [part | chunk(rest, size)]
  end
end
