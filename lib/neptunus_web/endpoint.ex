defmodule NeptunusWeb.Endpoint do
  @moduledoc """
  The web edge: yaws, embedded under this supervisor (`:one_for_all`), serving

    * `priv/static` (the operator page and its assets) at `/`,
    * the HTTP API (`NeptunusWeb.API`) under `/api`,
    * the Phoenix Channels v2 WebSocket (`NeptunusWeb.Socket`) at `/socket/websocket`,
    * the vehicles' cameras (`NeptunusWeb.CameraStream`) at `/camera/<id>.mjpg`.

  It starts last in the application and so stops first. Options come from
  `config :neptunus, :endpoint` (`%{port, bind, tls}`, validated by `Neptunus.Config`):
  with `tls: %{certfile, keyfile}` it serves HTTPS and `wss:` only (yaws sconf `ssl`).

  Every request passes `NeptunusWeb.Guard` first (the `Host` check against DNS rebinding)
  and every response gets its security headers (`Content-Security-Policy`,
  `X-Frame-Options`, `X-Content-Type-Options`).

  The login rate limiter (`NeptunusWeb.Auth.RateLimit`) runs here too, before yaws.
  """
  use Supervisor

  require Logger

  @server_id ~c"neptunus"
  @default_send_timeout_ms 15_000

  @spec start_link(Neptunus.Config.endpoint()) :: Supervisor.on_start()
  def start_link(config), do: Supervisor.start_link(__MODULE__, config, name: __MODULE__)

  @doc "The URL the endpoint serves on."
  @spec url() :: String.t()
  def url do
    %{port: port, bind: bind} = config = Application.fetch_env!(:neptunus, :endpoint)

    host =
      case bind do
        {0, 0, 0, 0} -> "127.0.0.1"
        {0, 0, 0, 0, 0, 0, 0, 0} -> "[::1]"
        {_, _, _, _} -> :inet.ntoa(bind)
        _ -> "[#{:inet.ntoa(bind)}]"
      end

    scheme = if Map.get(config, :tls), do: "https", else: "http"
    "#{scheme}://#{host}:#{port}"
  end

  @impl true
  def init(%{port: port, bind: bind} = config) do
    docroot = Application.app_dir(:neptunus, "priv/static") |> String.to_charlist()
    logdir = Path.join(System.tmp_dir!(), "neptunus-yaws-#{port}")
    File.mkdir_p!(logdir)

    gconf = [
      id: @server_id,
      logdir: String.to_charlist(logdir),
      cache_refresh_secs: 1,
      flags: [copy_error_log: false]
    ]

    sconf = [
      port: port,
      listen: bind,
      servername: ~c"neptunus",
      docroot: docroot,
      appmods: [
        {~c"/api", NeptunusWeb.API},
        {~c"/socket", NeptunusWeb.Socket},
        {~c"/camera", NeptunusWeb.CameraStream}
      ],
      flags: [access_log: false, auth_log: false],
      # every request: the Host check first, the security headers on every response
      arg_rewrite_mod: NeptunusWeb.Guard,
      extra_response_headers: [{:extramod, NeptunusWeb.Guard}],
      # Accepted sockets inherit these. Without nodelay, Nagle holds each small reply until
      # the client's delayed ACK (~40 ms): measured reply p90 43 ms → 1.4 ms with it.
      # A send that cannot go on for send_timeout_ms (the client stopped reading: a frozen
      # tab, a dead link the kernel still holds) closes the connection; without it the
      # sender would wait forever while its mailbox (telemetry, camera frames) grows.
      soptions: [
        listen_opts: [
          backlog: 1024,
          nodelay: true,
          send_timeout: send_timeout_ms(),
          send_timeout_close: true
        ]
      ]
    ]

    if Map.get(config, :tls) == nil and not match?({127, _, _, _}, bind) and
         bind != {0, 0, 0, 0, 0, 0, 0, 1} do
      Logger.warning(
        "serving #{:inet.ntoa(bind)}:#{port} without TLS: passwords and login tokens cross " <>
          "the network in clear text (set NEPTUNUS_TLS_CERT and NEPTUNUS_TLS_KEY)"
      )
    end

    sconf =
      case Map.get(config, :tls) do
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

    Supervisor.init([NeptunusWeb.Auth.RateLimit | yaws_children] ++ [listener],
      strategy: :one_for_all
    )
  end

  @doc """
  How long (ms) a send to a client may wait for the client to read before the connection
  is closed: `config :neptunus, :send_timeout_ms`, default #{@default_send_timeout_ms}.
  """
  @spec send_timeout_ms() :: pos_integer()
  def send_timeout_ms,
    do: Application.get_env(:neptunus, :send_timeout_ms, @default_send_timeout_ms)

  @doc false
  # Opens the listener once yaws' processes are up.
  def listen(gc, sclist) do
    case :yaws_api.setconf(gc, sclist) do
      :ok -> :ignore
      {:error, reason} -> {:error, {:endpoint_listen_failed, reason}}
    end
  end
end
