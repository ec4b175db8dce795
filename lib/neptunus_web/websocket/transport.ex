defmodule NeptunusWeb.WebSocket.Transport do
  @moduledoc """
  The TCP (or TLS) socket under a WebSocket connection, used directly by the connection's
  process: what yaws' own send and options do not give.

    * `write/2` sends bytes as they are. A broadcast is encoded once and its binary shared by
      every connection that receives it; sent as a frame header written by the connection
      (`NeptunusWeb.Socket.WsFrame`) and that binary, the connection holds only the few
      header bytes, where yaws' send would copy header and payload into one new binary per
      connection.
    * `limit_unsent/2` lets the kernel hold only so many of a connection's bytes unsent
      (Linux's `TCP_NOTSENT_LOWAT`, plain and TLS sockets alike). Without it the kernel grows
      the send buffer to megabytes for a slow client and its backlog forms there, where
      nothing can drop stale data; with it the backlog forms in the connection's mailbox,
      where the connection can.
    * `connected?/1` tells whether the socket is still open. The endpoint's send timeout
      closes a socket whose client stopped reading without telling yaws, so a connection
      looks when it finds itself behind and at its idle checks.

  The socket comes from yaws' `#ws_state{}` in `handle_open/2` (`socket/1`); before that a
  connection has none (nil), and these functions leave it to yaws.
  """
  import NeptunusWeb.Endpoint.Yaws, only: [ws_state: 2]

  @typedoc "A WebSocket's socket: plain TCP, or TLS as yaws names it."
  @type socket :: :inet.socket() | {:ssl, :ssl.sslsocket()}

  @ipproto_tcp 6
  @tcp_notsent_lowat 25

  @doc "The socket of a WebSocket connection, from yaws' `#ws_state{}` (`handle_open/2`)."
  @spec socket(tuple()) :: socket() | nil
  def socket(ws_state), do: ws_state(ws_state, :sock)

  @doc """
  Sends `data` (a whole frame, or frames) on the socket. The result is yaws' own: a socket
  that the send timeout closed answers an error (`connected?/1` finds it later too).
  """
  @spec write(socket(), iodata()) :: :ok | {:error, term()}
  def write({:ssl, sock}, data), do: :ssl.send(sock, data)
  def write(sock, data), do: :gen_tcp.send(sock, data)

  @doc """
  On Linux, lets the kernel take more of the connection's bytes only while fewer than
  `bytes` of them wait there unsent (`TCP_NOTSENT_LOWAT`); nil or another OS: the kernel's
  own buffer. Best effort: a kernel without the option keeps its larger buffer.
  """
  @spec limit_unsent(socket() | nil, pos_integer() | nil) :: :ok
  def limit_unsent(sock, bytes) do
    case :os.type() do
      {:unix, :linux} when is_integer(bytes) and bytes > 0 and sock != nil ->
        _ = setopts(sock, [{:raw, @ipproto_tcp, @tcp_notsent_lowat, <<bytes::native-32>>}])
        :ok

      _ ->
        :ok
    end
  end

  @doc "Whether the socket is still open (true before the connection has one)."
  @spec connected?(socket() | nil) :: boolean()
  def connected?(nil), do: true
  def connected?({:ssl, sock}), do: match?({:ok, _}, :ssl.peername(sock))
  def connected?(sock), do: match?({:ok, _}, :inet.peername(sock))

  defp setopts({:ssl, sock}, opts), do: :ssl.setopts(sock, opts)
  defp setopts(sock, opts), do: :inet.setopts(sock, opts)
end
