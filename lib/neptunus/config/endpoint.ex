defmodule Neptunus.Config.Endpoint do
  @moduledoc """
  Where the node listens (`config :neptunus, :endpoint`, see `NeptunusWeb.Endpoint`):
  `NEPTUNUS_PORT` (TCP port for HTTP and WebSocket, default 4000), `NEPTUNUS_BIND` (IPv4/IPv6
  address, default `127.0.0.1`) and `NEPTUNUS_MAX_CONNECTIONS` (client connections at once,
  1..1048576; unset: derived from the file descriptor limit).

  `web_settings!/1` builds the web layer's settings (`NeptunusWeb.Endpoint.Settings`) from the
  application's configuration, once, at boot; the defaults of the web layer's tuning keys
  are written here and nowhere else.
  """

  alias Neptunus.Config

  @type endpoint :: %{port: :inet.port_number(), bind: :inet.ip_address()}

  @doc """
  Endpoint settings from the environment map.

      iex> Neptunus.Config.Endpoint.endpoint!(%{}, 4000)
      %{port: 4000, bind: {127, 0, 0, 1}}

      iex> Neptunus.Config.Endpoint.endpoint!(%{"NEPTUNUS_PORT" => "8080", "NEPTUNUS_BIND" => "0.0.0.0"}, 4000)
      %{port: 8080, bind: {0, 0, 0, 0}}
  """
  @spec endpoint!(Config.env(), :inet.port_number()) :: endpoint()
  def endpoint!(env, default_port) do
    %{
      port: port!(Map.get(env, "NEPTUNUS_PORT"), default_port),
      bind: bind!(Map.get(env, "NEPTUNUS_BIND", "127.0.0.1"))
    }
  end

  @doc """
  The most client connections (HTTP and WebSocket) served at once: `NEPTUNUS_MAX_CONNECTIONS`,
  1..1048576, or nil when unset (`NeptunusWeb.Endpoint` derives it from the descriptor limit,
  and lowers a configured value the limit cannot hold).

      iex> Neptunus.Config.Endpoint.max_connections!(%{})
      nil
      iex> Neptunus.Config.Endpoint.max_connections!(%{"NEPTUNUS_MAX_CONNECTIONS" => "500"})
      500
  """
  @spec max_connections!(Config.env()) :: pos_integer() | nil
  def max_connections!(env),
    do: Config.env_integer!(env, "NEPTUNUS_MAX_CONNECTIONS", nil, 1..1_048_576)

  # the web layer's tuning keys (`config :neptunus, key: value`) and their defaults
  @web_defaults [
    # a send to a client that has not read for this long closes the connection
    send_timeout_ms: 15_000,
    # the most time a client has to send a request's head (and a kept-alive connection to
    # send its next request)
    header_timeout_ms: 5_000,
    # a WebSocket silent this long is closed (the phoenix client heartbeats every 30 s)
    socket_idle_timeout_ms: 60_000,
    # a piloting connection runs at :high while it sends at most this many frames per second
    pilot_frames_per_s: 200,
    # a connection with this many messages waiting drops stale telemetry frames
    socket_backlog: 8,
    # the kernel holds at most this many bytes of a connection's frames unsent (Linux,
    # TCP_NOTSENT_LOWAT); nil: the kernel's own
    socket_unsent_bytes: 4_096
  ]

  @doc """
  The web layer's settings from the application's configuration `app_env` (as
  `Application.get_all_env/1` returns it): `:endpoint` (required, see `endpoint!/2`), `:auth`
  (`Neptunus.Config.Auth`; unset keys: local mode's), the recordings directory of
  `:recording`, and the tuning keys #{inspect(Keyword.keys(@web_defaults))}, each positive
  integer, defaults #{inspect(@web_defaults)}. A bad value raises `ArgumentError` naming it.

      iex> settings = Neptunus.Config.Endpoint.web_settings!(endpoint: %{port: 4000, bind: {127, 0, 0, 1}}, socket_backlog: 16)
      iex> {settings.backlog, settings.idle_timeout_ms, settings.auth.mode, settings.recording_dir}
      {16, 60000, :local, nil}

      iex> Neptunus.Config.Endpoint.web_settings!(endpoint: %{port: 4000, bind: {127, 0, 0, 1}}, socket_backlog: 0)
      ** (ArgumentError) config :neptunus, socket_backlog: 0 is not valid: expected a positive integer
  """
  @spec web_settings!(keyword()) :: NeptunusWeb.Endpoint.Settings.t()
  def web_settings!(app_env) do
    endpoint =
      case Keyword.get(app_env, :endpoint) do
        %{port: port, bind: bind} = endpoint when is_integer(port) and is_tuple(bind) ->
          endpoint

        other ->
          raise ArgumentError,
                "config :neptunus, endpoint: #{inspect(other)} is not valid: expected " <>
                  "%{port: port, bind: address} (see Neptunus.Config.Endpoint.endpoint!/2)"
      end

    tune = fn key -> tuning!(key, Keyword.get(app_env, key, @web_defaults[key])) end

    %NeptunusWeb.Endpoint.Settings{
      port: endpoint.port,
      bind: endpoint.bind,
      tls: Map.get(endpoint, :tls),
      max_connections: Map.get(endpoint, :max_connections),
      send_timeout_ms: tune.(:send_timeout_ms),
      header_timeout_ms: tune.(:header_timeout_ms),
      idle_timeout_ms: tune.(:socket_idle_timeout_ms),
      pilot_frames_per_s: tune.(:pilot_frames_per_s),
      backlog: tune.(:socket_backlog),
      unsent_bytes: tune.(:socket_unsent_bytes),
      auth: Map.merge(Neptunus.Config.Auth.local(), Map.new(Keyword.get(app_env, :auth, %{}))),
      recording_dir: recording_dir(Keyword.get(app_env, :recording)),
      firmware_record: Keyword.get(app_env, :firmware_record)
    }
  end

  defp tuning!(_key, value) when is_integer(value) and value > 0, do: value
  defp tuning!(:socket_unsent_bytes, nil), do: nil

  defp tuning!(key, value) do
    raise ArgumentError,
          "config :neptunus, #{key}: #{inspect(value)} is not valid: expected a positive integer"
  end

  defp recording_dir(nil), do: nil
  defp recording_dir(recording), do: Map.get(Map.new(recording), :dir)

  defp port!(nil, default), do: default

  defp port!(value, _default) do
    case Integer.parse(String.trim(value)) do
      {port, ""} when port in 1..65_535 -> port
      _ -> Config.bad!("NEPTUNUS_PORT", value, "a TCP port number 1..65535")
    end
  end

  defp bind!(value) do
    case :inet.parse_address(String.to_charlist(String.trim(value))) do
      {:ok, address} ->
        address

      {:error, _} ->
        Config.bad!("NEPTUNUS_BIND", value, "an IP address such as 127.0.0.1 or 0.0.0.0")
    end
  end
end
