defmodule NeptunusWeb.Test.WSClient do
  @moduledoc """
  A wire-level RFC 6455 WebSocket client over `:gen_tcp`, for tests.

  One process per connection. It reports everything to its owner process
  (the test, by default) as messages:

    * `{:ws, pid, {:text, binary}}` and `{:ws, pid, {:binary, binary}}` — a
      complete message (fragments are reassembled; text is not checked for
      valid UTF-8)
    * `{:ws, pid, {:pong, payload}}` — a pong from the server (pings from the
      server are answered automatically and not reported)
    * `{:ws, pid, {:close, code, reason}}` — the server's close frame (code
      1005 when it carried no status)
    * `{:ws, pid, {:error, reason}}` — the server broke the protocol (masked
      frame, reserved bits, unknown opcode, …); the client then sends close
      1002 and drops the connection
    * `{:ws, pid, :closed}` — the TCP connection is gone; always the last
      message, after which the process has exited

  Frames the client sends are masked unless `send_frame/4` is told otherwise.
  The process monitors its owner and exits when the owner does.

  On top of the socket there are Phoenix Channels v2 helpers (`push/6`,
  `recv_frame/2`, `recv_until/3`, `join/4`). They use `:jiffy` directly, not
  `NeptunusWeb.Channels.Wire`, so that the codec under test is not trusted by
  its own test client. The receive helpers must run in the owner process and
  raise `ExUnit.AssertionError` on timeout or when the connection closes.
  """

  use GenServer

  @guid "258EAFA5-E914-47DA-95CA-C5AB0DC85B11"

  @opcodes %{continuation: 0, text: 1, binary: 2, close: 8, ping: 9, pong: 10}

  @type opcode :: :continuation | :text | :binary | :close | :ping | :pong | 0..15
  @type frame :: [term()]

  defstruct [
    :socket,
    :owner,
    :owner_ref,
    buffer: <<>>,
    fragments: nil,
    close_sent?: false,
    close_timer: nil
  ]

  @typedoc """
  * `socket` — the TCP socket, `active: :once`
  * `owner`, `owner_ref` — process receiving the reports and its monitor
  * `buffer` — received bytes not yet forming a complete frame
  * `fragments` — `{type, iodata}` of a fragmented message in progress, or `nil`
  * `close_sent?` — a close frame has been sent (no data may follow)
  * `close_timer` — drops TCP if the server does not finish the close handshake
  """
  @type t :: %__MODULE__{
          socket: :gen_tcp.socket(),
          owner: pid(),
          owner_ref: reference(),
          buffer: binary(),
          fragments: {:text | :binary, iodata()} | nil,
          close_sent?: boolean(),
          close_timer: reference() | nil
        }

  @doc """
  Connects to `ws://host:port<path_and_query>` and performs the opening
  handshake.

  Options:
    * `:host` — default `"127.0.0.1"`
    * `:headers` — extra request headers, a list of `{name, value}` (a `Host` here
      replaces the default `host:port`)
    * `:owner` — process that receives the reports, default `self()`
    * `:timeout` — for connect and handshake, ms, default `Neptunus.Test.Patience.ms/0`
    * `:paused` — `true`: read nothing after the handshake until `resume/1` (a client that
      stops reading, for slow-client tests); default `false`
    * `:recbuf` — the socket's receive buffer in bytes (small: a paused client's buffers
      fill sooner)

  Errors: `{:error, {:http_status, code, %{headers: [{name, value}], body: binary}}}`
  when the server answers other than 101 (header names downcased);
  `{:error, {:bad_handshake, why}}` when a 101 lacks the right
  `Upgrade`/`Connection`/`Sec-WebSocket-Accept`; `{:error, :timeout}`;
  `{:error, :closed}`; or a `:gen_tcp.connect/4` error.
  """
  @spec connect(:inet.port_number(), String.t(), keyword()) :: {:ok, pid()} | {:error, term()}
  def connect(port, path_and_query, opts \\ []) do
    host = Keyword.get(opts, :host, "127.0.0.1")
    owner = Keyword.get(opts, :owner, self())
    timeout = Keyword.get(opts, :timeout, Neptunus.Test.Patience.ms())
    deadline = System.monotonic_time(:millisecond) + timeout

    tcp_opts =
      [:binary, active: false, packet: :raw, nodelay: true] ++
        if(opts[:recbuf], do: [recbuf: opts[:recbuf]], else: [])

    with {:ok, socket} <- :gen_tcp.connect(String.to_charlist(host), port, tcp_opts, timeout) do
      case handshake(socket, host, port, path_and_query, opts, deadline) do
        {:ok, rest} ->
          {:ok, pid} = GenServer.start(__MODULE__, {socket, owner, rest})
          :ok = :gen_tcp.controlling_process(socket, pid)
          unless opts[:paused], do: GenServer.cast(pid, :activate)
          {:ok, pid}

        {:error, _} = error ->
          :gen_tcp.close(socket)
          error
      end
    end
  end

  @doc "Starts reading a client connected with `paused: true`."
  @spec resume(pid()) :: :ok
  def resume(pid), do: GenServer.cast(pid, :activate)

  @doc "Sends a text message (one masked frame)."
  @spec send_text(pid(), iodata()) :: :ok | {:error, term()}
  def send_text(pid, data), do: send_frame(pid, :text, data, [])

  @doc "Sends a binary message (one masked frame)."
  @spec send_binary(pid(), iodata()) :: :ok | {:error, term()}
  def send_binary(pid, data), do: send_frame(pid, :binary, data, [])

  @doc "Encodes `term` with jiffy (`nil` → `null`) and sends it as text."
  @spec send_json(pid(), term()) :: :ok | {:error, term()}
  def send_json(pid, term), do: send_text(pid, json_encode(term))

  @doc """
  Sends one raw frame, for protocol tests.

  `opcode` is an atom (`:continuation`, `:text`, `:binary`, `:close`,
  `:ping`, `:pong`) or any integer 0..15. Options:
    * `:fin` — default `true`; `false` starts/continues a fragmented message
    * `:mask` — default `true`; `false` sends an unmasked (illegal) frame
    * `:rsv` — reserved bits 0..7, default 0

  A close frame sent this way is raw: the client does not treat it as the
  start of the close handshake (use `close/3`).
  """
  @spec send_frame(pid(), opcode(), iodata(), keyword()) :: :ok | {:error, term()}
  def send_frame(pid, opcode, payload, opts \\ []) do
    safe_call(pid, {:send, frame(opcode_number(opcode), payload, opts)})
  end

  @doc "Sends raw bytes on the socket, not framed."
  @spec send_raw(pid(), iodata()) :: :ok | {:error, term()}
  def send_raw(pid, bytes), do: safe_call(pid, {:send, bytes})

  @doc """
  Starts the closing handshake: sends a close frame with `code` and
  `reason`. The owner then gets the server's `{:close, code, reason}` and
  `:closed`; TCP is dropped after `Neptunus.Test.Patience.ms/0` if the server
  does not answer.
  """
  @spec close(pid(), non_neg_integer(), String.t()) :: :ok | {:error, term()}
  def close(pid, code \\ 1000, reason \\ ""), do: safe_call(pid, {:close, code, reason})

  # Phoenix Channels v2 helpers (run in the owner process)

  @doc "Sends the v2 frame `[join_ref, ref, topic, event, payload]`."
  @spec push(pid(), String.t() | nil, String.t() | nil, String.t(), String.t(), map()) ::
          :ok | {:error, term()}
  def push(pid, join_ref, ref, topic, event, payload) do
    send_json(pid, [join_ref, ref, topic, event, payload])
  end

  @doc """
  Receives the next text message from `pid` and returns it decoded as
  `[join_ref, ref, topic, event, payload]` (maps with string keys, `null` as
  `nil`). Raises on timeout, on close and on a text that is not such a list.
  """
  @spec recv_frame(pid(), timeout()) :: frame()
  def recv_frame(pid, timeout \\ Neptunus.Test.Patience.ms()) do
    receive do
      {:ws, ^pid, {:text, text}} ->
        decode_frame!(text)

      {:ws, ^pid, {:close, code, reason}} ->
        fail("connection closed (#{code} #{inspect(reason)})")

      {:ws, ^pid, :closed} ->
        fail("connection closed")

      {:ws, ^pid, {:error, reason}} ->
        fail("protocol error from server: #{inspect(reason)}")
    after
      timeout -> fail("no frame received within #{timeout} ms")
    end
  end

  @doc """
  Receives frames until `fun.(frame)` is truthy and returns that frame;
  frames before it are discarded. `timeout` bounds the whole wait.
  """
  @spec recv_until(pid(), (frame() -> as_boolean(term())), timeout()) :: frame()
  def recv_until(pid, fun, timeout \\ Neptunus.Test.Patience.ms()) do
    deadline = System.monotonic_time(:millisecond) + timeout
    do_recv_until(pid, fun, deadline, timeout, [])
  end

  @doc """
  Joins `topic`: pushes `phx_join` with `params` (ref = `join_ref`) and waits
  for the matching `phx_reply` (`Neptunus.Test.Patience`). Without `join_ref` a unique one is
  generated; pass your own when you need it for later pushes.
  """
  @spec join(pid(), String.t(), map(), String.t() | nil) :: {:ok, map()} | {:error, map()}
  def join(pid, topic, params \\ %{}, join_ref \\ nil) do
    join_ref = join_ref || unique_ref()
    :ok = push(pid, join_ref, join_ref, topic, "phx_join", params)

    [_, _, _, _, %{"status" => status, "response" => response}] =
      recv_until(
        pid,
        &match?([^join_ref, ^join_ref, ^topic, "phx_reply", %{"status" => _}], &1),
        Neptunus.Test.Patience.ms()
      )

    case status do
      "ok" -> {:ok, response}
      "error" -> {:error, response}
      other -> fail("phx_reply with unknown status #{inspect(other)}")
    end
  end

  @doc "A fresh ref string, unique within the VM."
  @spec unique_ref() :: String.t()
  def unique_ref, do: Integer.to_string(System.unique_integer([:positive, :monotonic]))

  # Callbacks

  @impl true
  def init({socket, owner, rest}) do
    {:ok,
     %__MODULE__{socket: socket, owner: owner, owner_ref: Process.monitor(owner), buffer: rest}}
  end

  @impl true
  def handle_cast(:activate, state), do: handle_data(<<>>, state)

  @impl true
  def handle_call({:send, _bytes}, _from, %{close_sent?: true} = state),
    do: {:reply, {:error, :closing}, state}

  def handle_call({:send, bytes}, _from, state),
    do: {:reply, :gen_tcp.send(state.socket, bytes), state}

  def handle_call({:close, _code, _reason}, _from, %{close_sent?: true} = state),
    do: {:reply, {:error, :closing}, state}

  def handle_call({:close, code, reason}, _from, state) do
    reply = :gen_tcp.send(state.socket, frame(8, <<code::16, reason::binary>>, []))
    timer = Process.send_after(self(), :close_timeout, Neptunus.Test.Patience.ms())
    {:reply, reply, %{state | close_sent?: true, close_timer: timer}}
  end

  @impl true
  def handle_info({:tcp, socket, data}, %{socket: socket} = state), do: handle_data(data, state)
  def handle_info({:tcp_closed, socket}, %{socket: socket} = state), do: closed(state)
  def handle_info({:tcp_error, socket, _reason}, %{socket: socket} = state), do: closed(state)
  def handle_info(:close_timeout, state), do: closed(state)

  def handle_info({:DOWN, ref, :process, _, _}, %{owner_ref: ref} = state) do
    :gen_tcp.close(state.socket)
    {:stop, :normal, state}
  end

  def handle_info(_other, state), do: {:noreply, state}

  # Receiving

  defp handle_data(data, state) do
    case parse_frames(state.buffer <> data, state) do
      {:continue, rest, state} ->
        :ok = :inet.setopts(state.socket, active: :once)
        {:noreply, %{state | buffer: rest}}

      {:stop, state} ->
        closed(state)
    end
  end

  defp parse_frames(buffer, state) do
    case parse_frame(buffer) do
      :more ->
        {:continue, buffer, state}

      {:error, reason} ->
        protocol_error(reason, state)

      {:ok, fin, opcode, payload, rest} ->
        case handle_frame(fin, opcode, payload, state) do
          {:ok, state} -> parse_frames(rest, state)
          {:stop, state} -> {:stop, state}
        end
    end
  end

  defp parse_frame(<<fin::1, rsv::3, opcode::4, masked::1, len7::7, rest::binary>>) do
    with {:ok, len, rest} <- payload_length(len7, rest),
         {:ok, key, rest} <- mask_key(masked, rest),
         <<payload::binary-size(len), rest::binary>> <- rest do
      cond do
        rsv != 0 -> {:error, "reserved bits set (#{rsv})"}
        masked == 1 -> {:error, "masked frame from server"}
        opcode in [3, 4, 5, 6, 7] or opcode > 10 -> {:error, "unknown opcode #{opcode}"}
        opcode >= 8 and (fin == 0 or len > 125) -> {:error, "invalid control frame"}
        true -> {:ok, fin == 1, opcode, unmask(payload, key), rest}
      end
    else
      _ -> :more
    end
  end

  defp parse_frame(_short), do: :more

  defp payload_length(126, <<len::16, rest::binary>>), do: {:ok, len, rest}
  defp payload_length(127, <<len::64, rest::binary>>), do: {:ok, len, rest}
  defp payload_length(len, rest) when len < 126, do: {:ok, len, rest}
  defp payload_length(_, _), do: :more

  defp mask_key(0, rest), do: {:ok, nil, rest}
  defp mask_key(1, <<key::binary-4, rest::binary>>), do: {:ok, key, rest}
  defp mask_key(1, _), do: :more

  # data frames
  defp handle_frame(_fin, 0, _payload, %{fragments: nil} = state),
    do: protocol_error("continuation frame without a started message", state)

  defp handle_frame(fin, 0, payload, %{fragments: {type, acc}} = state),
    do: data(fin, type, [acc, payload], state)

  defp handle_frame(_fin, opcode, _payload, %{fragments: {_, _}} = state) when opcode in [1, 2],
    do: protocol_error("new data frame inside a fragmented message", state)

  defp handle_frame(fin, 1, payload, state), do: data(fin, :text, payload, state)
  defp handle_frame(fin, 2, payload, state), do: data(fin, :binary, payload, state)

  # control frames
  defp handle_frame(true, 9, payload, state) do
    unless state.close_sent?, do: :gen_tcp.send(state.socket, frame(10, payload, []))
    {:ok, state}
  end

  defp handle_frame(true, 10, payload, state) do
    report(state, {:pong, payload})
    {:ok, state}
  end

  defp handle_frame(true, 8, payload, state) do
    {code, reason} =
      case payload do
        <<code::16, reason::binary>> -> {code, reason}
        _ -> {1005, ""}
      end

    report(state, {:close, code, reason})

    unless state.close_sent? do
      echo = if code == 1005, do: <<>>, else: <<code::16>>
      :gen_tcp.send(state.socket, frame(8, echo, []))
    end

    {:stop, state}
  end

  defp data(true, type, iodata, state) do
    report(state, {type, IO.iodata_to_binary(iodata)})
    {:ok, %{state | fragments: nil}}
  end

  defp data(false, type, iodata, state), do: {:ok, %{state | fragments: {type, iodata}}}

  defp protocol_error(reason, state) do
    report(state, {:error, reason})
    unless state.close_sent?, do: :gen_tcp.send(state.socket, frame(8, <<1002::16>>, []))
    {:stop, state}
  end

  defp closed(state) do
    :gen_tcp.close(state.socket)
    report(state, :closed)
    {:stop, :normal, state}
  end

  defp report(state, event), do: send(state.owner, {:ws, self(), event})

  # Sending

  defp frame(opcode, payload, opts) do
    payload = IO.iodata_to_binary(payload)
    fin = if Keyword.get(opts, :fin, true), do: 1, else: 0
    rsv = Keyword.get(opts, :rsv, 0)
    len = byte_size(payload)

    len_bits =
      cond do
        len < 126 -> <<len::7>>
        len < 0x10000 -> <<126::7, len::16>>
        true -> <<127::7, len::64>>
      end

    if Keyword.get(opts, :mask, true) do
      key = :crypto.strong_rand_bytes(4)
      masked = unmask(payload, key)
      <<fin::1, rsv::3, opcode::4, 1::1, len_bits::bitstring, key::binary, masked::binary>>
    else
      <<fin::1, rsv::3, opcode::4, 0::1, len_bits::bitstring, payload::binary>>
    end
  end

  defp unmask(payload, nil), do: payload
  defp unmask(<<>>, _key), do: <<>>

  defp unmask(payload, key) do
    size = byte_size(payload)
    keystream = key |> :binary.copy(div(size, 4) + 1) |> binary_part(0, size)
    :crypto.exor(payload, keystream)
  end

  defp opcode_number(opcode) when is_integer(opcode) and opcode in 0..15, do: opcode
  defp opcode_number(opcode) when is_map_key(@opcodes, opcode), do: Map.fetch!(@opcodes, opcode)

  defp safe_call(pid, request) do
    GenServer.call(pid, request)
  catch
    :exit, _ -> {:error, :closed}
  end

  # Handshake (runs in the caller, socket passive)

  defp handshake(socket, host, port, path, opts, deadline) do
    key = Base.encode64(:crypto.strong_rand_bytes(16))

    extra = Keyword.get(opts, :headers, [])

    host_header? =
      Enum.any?(extra, fn {name, _} -> String.downcase(to_string(name)) == "host" end)

    headers =
      if(host_header?, do: [], else: [{"Host", "#{host}:#{port}"}]) ++
        [
          {"Upgrade", "websocket"},
          {"Connection", "Upgrade"},
          {"Sec-WebSocket-Key", key},
          {"Sec-WebSocket-Version", "13"}
        ] ++ extra

    request = [
      "GET #{path} HTTP/1.1\r\n",
      Enum.map(headers, fn {name, value} -> [to_string(name), ": ", to_string(value), "\r\n"] end),
      "\r\n"
    ]

    with :ok <- :gen_tcp.send(socket, request),
         {:ok, head, rest} <- recv_head(socket, <<>>, deadline),
         {:ok, code, headers} <- parse_head(head) do
      if code == 101 do
        check_upgrade(headers, key, rest)
      else
        {:error,
         {:http_status, code,
          %{headers: headers, body: read_body(socket, headers, rest, deadline)}}}
      end
    end
  end

  defp recv_head(socket, acc, deadline) do
    case :binary.split(acc, "\r\n\r\n") do
      [head, rest] ->
        {:ok, head, rest}

      [_] ->
        case recv(socket, deadline) do
          {:ok, data} -> recv_head(socket, acc <> data, deadline)
          {:error, _} = error -> error
        end
    end
  end

  defp recv(socket, deadline) do
    :gen_tcp.recv(socket, 0, max(deadline - System.monotonic_time(:millisecond), 0))
  end

  defp parse_head(head) do
    [status_line | lines] = String.split(head, "\r\n")

    with ["HTTP/1." <> _, code | _] <- String.split(status_line, " ", parts: 3),
         {code, ""} <- Integer.parse(code) do
      headers =
        for line <- lines, [name, value] <- [:binary.split(line, ":")] do
          {String.downcase(String.trim(name)), String.trim(value)}
        end

      {:ok, code, headers}
    else
      _ -> {:error, {:bad_handshake, "malformed status line #{inspect(status_line)}"}}
    end
  end

  defp check_upgrade(headers, key, rest) do
    expected = Base.encode64(:crypto.hash(:sha, key <> @guid))
    accept = header(headers, "sec-websocket-accept")
    connection = headers |> header("connection") |> String.downcase() |> String.split(~r/\s*,\s*/)

    cond do
      String.downcase(header(headers, "upgrade")) != "websocket" ->
        {:error, {:bad_handshake, "missing Upgrade: websocket"}}

      "upgrade" not in connection ->
        {:error, {:bad_handshake, "missing Connection: Upgrade"}}

      accept != expected ->
        {:error, {:bad_handshake, "wrong Sec-WebSocket-Accept #{inspect(accept)}"}}

      true ->
        {:ok, rest}
    end
  end

  defp header(headers, name) do
    case List.keyfind(headers, name, 0) do
      {_, value} -> value
      nil -> ""
    end
  end

  # Best effort: Content-Length, chunked, or until close / deadline.
  defp read_body(socket, headers, acc, deadline) do
    cond do
      length = List.keyfind(headers, "content-length", 0) ->
        {_, value} = length
        recv_exactly(socket, acc, String.to_integer(value), deadline)

      {"transfer-encoding", "chunked"} in headers ->
        socket |> recv_all(acc, deadline, &chunked_done?/1) |> dechunk()

      true ->
        recv_all(socket, acc, deadline, fn _ -> false end)
    end
  end

  defp recv_exactly(_socket, acc, n, _deadline) when byte_size(acc) >= n,
    do: binary_part(acc, 0, n)

  defp recv_exactly(socket, acc, n, deadline) do
    case recv(socket, deadline) do
      {:ok, data} -> recv_exactly(socket, acc <> data, n, deadline)
      {:error, _} -> acc
    end
  end

  defp recv_all(socket, acc, deadline, done?) do
    if done?.(acc) do
      acc
    else
      case recv(socket, deadline) do
        {:ok, data} -> recv_all(socket, acc <> data, deadline, done?)
        {:error, _} -> acc
      end
    end
  end

  defp chunked_done?(acc), do: String.ends_with?(acc, "\r\n0\r\n\r\n") or acc == "0\r\n\r\n"

  defp dechunk(data) do
    with [size_line, rest] <- :binary.split(data, "\r\n"),
         {size, _} when size > 0 <- Integer.parse(size_line, 16),
         <<chunk::binary-size(size), "\r\n", rest::binary>> <- rest do
      chunk <> dechunk(rest)
    else
      _ -> <<>>
    end
  end

  # Channels helpers

  defp do_recv_until(pid, fun, deadline, timeout, skipped) do
    remaining = max(deadline - System.monotonic_time(:millisecond), 0)

    frame =
      try do
        recv_frame(pid, remaining)
      rescue
        e in ExUnit.AssertionError ->
          fail("""
          recv_until: #{e.message} (waited #{timeout} ms); \
          #{length(skipped)} frame(s) did not match:
          #{skipped |> Enum.reverse() |> Enum.take(-20) |> Enum.map_join("\n", &inspect/1)}
          """)
      end

    if fun.(frame), do: frame, else: do_recv_until(pid, fun, deadline, timeout, [frame | skipped])
  end

  defp decode_frame!(text) do
    case json_decode(text) do
      {:ok, [_, _, _, _, _] = frame} -> frame
      _ -> fail("not a Phoenix Channels v2 frame: #{inspect(text, limit: 200)}")
    end
  end

  defp json_encode(term), do: term |> :jiffy.encode([:use_nil]) |> IO.iodata_to_binary()

  defp json_decode(text) do
    {:ok, :jiffy.decode(text, [:return_maps, {:null_term, nil}])}
  catch
    _kind, reason -> {:error, reason}
  end

  defp fail(message), do: raise(ExUnit.AssertionError, message: message)
end
