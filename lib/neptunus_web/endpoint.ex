defmodule NeptunusWeb.Endpoint do
  @moduledoc """
  The web edge: yaws, embedded under this supervisor, serving

    * `priv/static` (the operator page and its assets) at `/`,
    * the HTTP API (`NeptunusWeb.API`) under `/api`,
    * the Phoenix Channels v2 WebSocket (`NeptunusWeb.Socket`) at `/socket/websocket`,
    * the vehicles' cameras: the video WebSocket (`NeptunusWeb.VideoSocket`) at
      `/video/<id>/websocket`, MJPEG for `<img>` (`NeptunusWeb.CameraStream`) at
      `/camera/<id>.mjpg`.

  It starts last in the application and so stops first. Its option is the web layer's
  settings (`NeptunusWeb.Endpoint.Settings`, built from the configuration once at boot by
  `Neptunus.Config.Endpoint.web_settings!/1`), which it stores for the connection processes
  when it starts: with `tls: %{certfile, keyfile}` it serves HTTPS and `wss:` only (yaws
  sconf `ssl`).

  Every request passes `NeptunusWeb.Endpoint.Guard` first (the `Host` check against DNS
  rebinding) and every response gets its security headers (`Content-Security-Policy`,
  `X-Frame-Options`, `X-Content-Type-Options`).

  What serves a request is elsewhere (the modules above); what the endpoint itself is made of
  sits beside it, in `lib/neptunus_web/endpoint/`:

    * `NeptunusWeb.Endpoint.Settings` — the web layer's settings, stored here at start;
    * `NeptunusWeb.Endpoint.Yaws` — yaws' records and the request helpers every module that
      yaws calls shares;
    * `NeptunusWeb.Endpoint.Guard` — the `Host` check and the security headers;
    * `NeptunusWeb.Endpoint.HeaderDeadline`, `NeptunusWeb.Endpoint.ConnectionLog` — the
      helpers below that protect the endpoint.

  ## Supervision

  `:rest_for_one`, in this order:

    1. `NeptunusWeb.Endpoint.Server` — yaws' own processes and the listener, `:one_for_all`
       (yaws' processes depend on each other: one of them lost and yaws restarts whole,
       closing every connection; its server process is killed rather than stopped, which
       would wait a second first);
    2. `NeptunusWeb.Auth.RateLimit` — the login rate limiter;
    3. `NeptunusWeb.Endpoint.ConnectionLog` — the count of connections closed to protect the
       endpoint;
    4. `NeptunusWeb.Endpoint.HeaderDeadline` — the deadline on request heads (it watches yaws'
       connection processes, so it restarts with yaws).

  A helper that crashes restarts alone (with the helpers after it) and never takes yaws or
  a connection with it: the pilot's WebSocket stays up. While a helper restarts, only a
  request that needs it at that instant fails (a login during the rate limiter's restart).

  ## Connections and file descriptors

  Every connection holds a descriptor, and yaws' acceptor exits when `accept` fails for want
  of one (`emfile`): that takes its listener down with every HTTP connection it holds, and
  a few times over, the endpoint with every WebSocket (the pilot's too). So the endpoint never lets connections reach the descriptor limit: yaws'
  `max_connections` is `connection_limit/2` of `NEPTUNUS_MAX_CONNECTIONS` and the VM's socket
  limit (`Neptunus.OS.socket_limit/0`), which leaves room for files, port programs and the
  recorder. A connection beyond it is accepted and closed at once, before anything is read
  from it; the established ones are not touched. yaws' log line for each is counted
  instead (`NeptunusWeb.Endpoint.ConnectionLog`: one warning at most every 10 s).

  A connection that holds a descriptor without completing a request is closed within
  `header_timeout_ms/0` (5 s by default): yaws' `keepalive_timeout` bounds each read of
  the request line and of each header (and the wait for the next request on a kept-alive
  connection), and `NeptunusWeb.Endpoint.HeaderDeadline` bounds the whole request head,
  against a client that trickles a byte at a time. WebSocket and camera connections, once upgraded or
  streaming, are not affected.
  """
  use Supervisor

  require Logger

  alias NeptunusWeb.Endpoint.Settings

  @server_id ~c"neptunus"
  # descriptors kept for everything but client connections: files, port programs, the
  # recorder's logs, the VM's own (at least this many, or 1/16 of the limit)
  @reserved_fds 64

  @spec start_link(Settings.t()) :: Supervisor.on_start()
  def start_link(%Settings{} = settings),
    do: Supervisor.start_link(__MODULE__, settings, name: __MODULE__)

  @doc "The URL the endpoint serves on."
  @spec url() :: String.t()
  def url, do: Settings.url(Settings.get())

  @impl true
  def init(%Settings{port: port, bind: bind} = settings) do
    # read by every connection process (NeptunusWeb.Endpoint.Settings)
    Settings.put(settings)
    docroot = Application.app_dir(:neptunus, "priv/static") |> String.to_charlist()
    logdir = Path.join(System.tmp_dir!(), "neptunus-yaws-#{port}")
    File.mkdir_p!(logdir)

    {max_connections, source} =
      connection_limit(settings.max_connections, Neptunus.OS.socket_limit())

    log_connection_limit(max_connections, source)

    gconf = [
      id: @server_id,
      logdir: String.to_charlist(logdir),
      cache_refresh_secs: 1,
      flags: [copy_error_log: false],
      # beyond this many connections yaws closes a new one as soon as it is accepted
      max_connections: max_connections,
      # how long yaws waits for the request line, each header line, the next request on a
      # kept-alive connection (and a TLS handshake) before it closes the connection
      keepalive_timeout: settings.header_timeout_ms
    ]

    sconf = [
      port: port,
      listen: bind,
      servername: ~c"neptunus",
      docroot: docroot,
      appmods: [
        {~c"/api", NeptunusWeb.API},
        {~c"/socket", NeptunusWeb.Socket},
        {~c"/camera", NeptunusWeb.CameraStream},
        {~c"/video", NeptunusWeb.VideoSocket}
      ],
      flags: [access_log: false, auth_log: false],
      # every request: the Host check first, the security headers on every response
      arg_rewrite_mod: NeptunusWeb.Endpoint.Guard,
      extra_response_headers: [{:extramod, NeptunusWeb.Endpoint.Guard}],
      # Accepted sockets inherit these. Without nodelay, Nagle holds each small reply until
      # the client's delayed ACK (~40 ms on every reply; figures in bench/README.md).
      # A send that cannot go on for send_timeout_ms (the client stopped reading: a frozen
      # tab, a dead link the kernel still holds) closes the connection; without it the
      # sender would wait forever while its mailbox (telemetry, camera frames) grows.
      soptions: [
        listen_opts: [
          backlog: 1024,
          nodelay: true,
          send_timeout: settings.send_timeout_ms,
          send_timeout_close: true
        ]
      ]
    ]

    if settings.tls == nil and not Neptunus.Config.Auth.loopback?(bind) do
      Logger.warning(
        "serving #{:inet.ntoa(bind)}:#{port} without TLS: passwords and login tokens cross " <>
          "the network in clear text (set NEPTUNUS_TLS_CERT and NEPTUNUS_TLS_KEY)"
      )
    end

    sconf =
      case settings.tls do
        %{certfile: cert, keyfile: key} ->
          sconf ++ [ssl: [certfile: String.to_charlist(cert), keyfile: String.to_charlist(key)]]

        nil ->
          sconf
      end

    {:ok, sclist, gc, yaws_children} =
      :yaws_api.embedded_start_conf(docroot, sconf, gconf, @server_id)

    listener = %{
      id: :listener,
      start: {__MODULE__, :listen, [gc, sclist]},
      restart: :transient
    }

    server = %{
      id: NeptunusWeb.Endpoint.Server,
      start:
        {Supervisor, :start_link,
         [Enum.map(yaws_children, &quick_server/1) ++ [listener], server_options()]},
      type: :supervisor
    }

    deadline = {NeptunusWeb.Endpoint.HeaderDeadline, timeout_ms: settings.header_timeout_ms}

    Supervisor.init(
      [server, NeptunusWeb.Auth.RateLimit, NeptunusWeb.Endpoint.ConnectionLog, deadline],
      strategy: :rest_for_one
    )
  end

  defp server_options, do: [strategy: :one_for_all, name: NeptunusWeb.Endpoint.Server]

  # yaws' server process, stopped in order, tells its listening process to stop, which
  # unlinks from it, closes the listening socket, shuts its connections down and then waits
  # a whole second (`timer:sleep(1000)`) before it looks whether they have ended; so when
  # another of yaws' processes crashes and the group restarts, the endpoint would be gone
  # for over a second. Given a moment to pass the stop on (the listener is unlinked by then:
  # no "Top proc died" error at a clean stop), it is killed, which takes whatever is still
  # linked to it down at once.
  @server_shutdown_ms 50

  defp quick_server({:yaws_server, start, restart, _shutdown, type, modules}),
    do: {:yaws_server, start, restart, @server_shutdown_ms, type, modules}

  defp quick_server(%{id: :yaws_server} = spec),
    do: Map.put(spec, :shutdown, @server_shutdown_ms)

  defp quick_server(spec), do: spec

  @doc """
  How long (ms) a send to a client may wait for the client to read before the connection
  is closed (`NeptunusWeb.Endpoint.Settings`, `config :neptunus, :send_timeout_ms`).
  """
  @spec send_timeout_ms() :: pos_integer()
  def send_timeout_ms, do: Settings.get().send_timeout_ms

  @doc """
  How long (ms) a client may take to send a request's head (request line and headers), and
  how long a kept-alive connection may wait for its next request
  (`NeptunusWeb.Endpoint.Settings`, `config :neptunus, :header_timeout_ms`).
  """
  @spec header_timeout_ms() :: pos_integer()
  def header_timeout_ms, do: Settings.get().header_timeout_ms

  @doc """
  The most connections to serve at once, given the configured maximum (nil: none configured)
  and the descriptors the VM can use for sockets, and where it came from. Each connection may
  hold a second descriptor (a file it is sent, a recording it exports), and
  #{@reserved_fds} descriptors or 1/16 of the limit, whichever is more, stay for files, port
  programs and the recorder: the limit is half of the rest. A configured maximum above that
  is lowered to it.

      iex> NeptunusWeb.Endpoint.connection_limit(nil, 1024)
      {480, :derived}
      iex> NeptunusWeb.Endpoint.connection_limit(100, 1024)
      {100, :configured}
      iex> NeptunusWeb.Endpoint.connection_limit(5000, 1024)
      {480, {:lowered, 5000}}
  """
  @spec connection_limit(pos_integer() | nil, pos_integer()) ::
          {pos_integer(), :derived | :configured | {:lowered, pos_integer()}}
  def connection_limit(configured, socket_limit)
      when (configured == nil or (is_integer(configured) and configured > 0)) and
             is_integer(socket_limit) and socket_limit > 0 do
    reserved = max(@reserved_fds, div(socket_limit, 16))
    derived = max(1, div(socket_limit - reserved, 2))

    cond do
      configured == nil -> {derived, :derived}
      configured <= derived -> {configured, :configured}
      true -> {derived, {:lowered, configured}}
    end
  end

  defp log_connection_limit(limit, :derived),
    do: Logger.info("serving at most #{limit} connections at once (from the descriptor limit)")

  defp log_connection_limit(limit, :configured),
    do: Logger.info("serving at most #{limit} connections at once (NEPTUNUS_MAX_CONNECTIONS)")

  defp log_connection_limit(limit, {:lowered, configured}) do
    Logger.warning(
      "NEPTUNUS_MAX_CONNECTIONS=#{configured} exceeds what #{Neptunus.OS.socket_limit()} " <>
        "file descriptors hold: serving at most #{limit} connections at once (raise the " <>
        "limit: LimitNOFILE in the systemd unit, `ulimit -n` elsewhere)"
    )
  end

  @doc false
  # Opens the listener once yaws' processes are up.
  def listen(gc, sclist) do
    case :yaws_api.setconf(gc, sclist) do
      :ok -> :ignore
      {:error, reason} -> {:error, {:endpoint_listen_failed, reason}}
    end
  end
end
