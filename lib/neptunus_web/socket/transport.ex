defmodule NeptunusWeb.Socket.Transport do
  @moduledoc """
  What the WebSocket endpoints share — the Channels socket (`NeptunusWeb.Socket`) and the
  video socket (`NeptunusWeb.VideoSocket`): who may connect (the same checks for both), and
  the connection's TCP socket under yaws.

    * `authorize/1` — the upgrade's `Origin`, `Host` and `token` (and `name` in local mode)
      decided by `NeptunusWeb.Auth.connect/1`;
    * `limit_unsent/1` — on Linux the kernel may hold only `unsent_bytes`
      (`NeptunusWeb.Settings`, default 4 096) of a connection's frames unsent
      (`TCP_NOTSENT_LOWAT`, plain and TLS sockets alike): without it the kernel grows the
      send buffer to megabytes and a slow client's backlog forms there, where nothing can
      drop stale data; with it the backlog forms in the connection's mailbox, where the
      connection drops what is stale (telemetry, whole groups of pictures);
    * `send_data/2` — a frame written straight to the socket (the shared binary of a
      broadcast behind a header, see `NeptunusWeb.Socket.WsFrame`), not through yaws;
    * `connected?/1` — whether the socket is still open: the endpoint's send timeout closes a
      socket whose client stopped reading without telling yaws.
  """
  import NeptunusWeb.Yaws

  @ipproto_tcp 6
  @tcp_notsent_lowat 25

  @typedoc "A connection's socket as yaws' WebSocket state holds it."
  @type sock :: port() | {:ssl, :ssl.sslsocket()} | nil

  @doc """
  Decides an upgrade request (yaws' `#arg{}`): the connection's user, or the HTTP status
  and reason to refuse it with (`NeptunusWeb.Auth.connect/1`).
  """
  @spec authorize(tuple()) :: {:ok, NeptunusWeb.Auth.user()} | {:error, 401 | 403, String.t()}
  def authorize(arg) do
    headers = arg(arg, :headers)
    params = query(arg)

    NeptunusWeb.Auth.connect(%{
      origin: header(headers, "origin"),
      host: text(headers(headers, :host)),
      token: params["token"],
      name: params["name"]
    })
  end

  @doc "The answer refusing a request: `status` and `{\"error\": reason}`."
  @spec http_error(pos_integer(), String.t()) :: list()
  def http_error(status, reason) do
    [{:status, status}, {:content, ~c"application/json", Neptunus.JSON.encode!(%{error: reason})}]
  end

  @doc "Limits the bytes the kernel holds unsent on `sock` (see the moduledoc); best effort."
  @spec limit_unsent(sock()) :: :ok
  def limit_unsent(sock) do
    case {:os.type(), NeptunusWeb.Settings.get().unsent_bytes} do
      {{:unix, :linux}, bytes} when is_integer(bytes) and bytes > 0 and sock != nil ->
        # a kernel without the option only keeps the larger buffer
        _ = setopts(sock, [{:raw, @ipproto_tcp, @tcp_notsent_lowat, <<bytes::native-32>>}])
        :ok

      _ ->
        :ok
    end
  end

  @doc "Writes `data` to the socket (the result as the socket gives it)."
  @spec send_data(sock(), iodata()) :: :ok | {:error, term()}
  def send_data({:ssl, sock}, data), do: :ssl.send(sock, data)
  def send_data(sock, data), do: :gen_tcp.send(sock, data)

  @doc "Whether the socket is still open (true before yaws hands it over)."
  @spec connected?(sock()) :: boolean()
  def connected?(nil), do: true
  def connected?({:ssl, sock}), do: match?({:ok, _}, :ssl.peername(sock))
  def connected?(sock), do: match?({:ok, _}, :inet.peername(sock))

  defp setopts({:ssl, sock}, opts), do: :ssl.setopts(sock, opts)
  defp setopts(sock, opts), do: :inet.setopts(sock, opts)
end
