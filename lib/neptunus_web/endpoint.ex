defmodule NeptunusWeb.Endpoint do
  @moduledoc """
  The web edge: yaws, embedded under this supervisor (`:one_for_all`), serving

    * `priv/static` (the operator page and its assets) at `/`,
    * the HTTP API (`NeptunusWeb.API`) under `/api`,
    * the Phoenix Channels v2 WebSocket (`NeptunusWeb.Socket`) at `/socket/websocket`.

  It starts last in the application and so stops first. Options come from
  `config :neptunus, :endpoint` (`%{port, bind}`, validated by `Neptunus.Config`).
  """
  use Supervisor

  @server_id ~c"neptunus"

  @spec start_link(Neptunus.Config.endpoint()) :: Supervisor.on_start()
  def start_link(config), do: Supervisor.start_link(__MODULE__, config, name: __MODULE__)

  @doc "The URL the endpoint serves on."
  @spec url() :: String.t()
  def url do
    %{port: port, bind: bind} = Application.fetch_env!(:neptunus, :endpoint)

    host =
      if bind in [{0, 0, 0, 0}, {0, 0, 0, 0, 0, 0, 0, 0}], do: "127.0.0.1", else: :inet.ntoa(bind)

    "http://#{host}:#{port}"
  end

  @impl true
  def init(%{port: port, bind: bind}) do
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
      appmods: [{~c"/api", NeptunusWeb.API}, {~c"/socket", NeptunusWeb.Socket}],
      flags: [access_log: false, auth_log: false]
    ]

    {:ok, sclist, gc, yaws_children} =
      :yaws_api.embedded_start_conf(docroot, sconf, gconf, @server_id)

    listener = %{
      id: :listener,
      start: {__MODULE__, :listen, [gc, sclist]},
      restart: :transient
    }

    Supervisor.init(yaws_children ++ [listener], strategy: :one_for_all)
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
