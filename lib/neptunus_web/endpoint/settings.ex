defmodule NeptunusWeb.Endpoint.Settings do
  @moduledoc """
  The web layer's settings: where the endpoint listens, its timeouts, the connections'
  flow control, the security configuration and the recordings directory.

  They are read from the application's configuration once, at boot, by
  `Neptunus.Config.Endpoint.web_settings!/1` (which holds every default), handed to
  `NeptunusWeb.Endpoint` as its option, and stored by the endpoint in `:persistent_term`
  when it starts: every connection process (a WebSocket, an API request, the `Host`
  guard) reads them with `get/0`, which copies nothing. Nothing in the web layer reads the
  application environment.

  `put/1` replaces them; besides the endpoint, only tests call it (to run a connection
  with another idle timeout, or the node in secure mode). Settings the endpoint gives yaws
  when it starts (port, timeouts, connection limit) change only with an endpoint restart;
  the others apply to the next connection or request. A `:persistent_term` update makes
  the VM scan every process once, so the settings are not for values that change often.
  """

  @enforce_keys [
    :port,
    :bind,
    :tls,
    :max_connections,
    :send_timeout_ms,
    :header_timeout_ms,
    :idle_timeout_ms,
    :pilot_frames_per_s,
    :backlog,
    :unsent_bytes,
    :auth,
    :recording_dir
  ]
  defstruct @enforce_keys ++ [firmware_record: nil]

  @typedoc """
    * `port`, `bind`, `tls`, `max_connections` — the listener (`Neptunus.Config.Endpoint`,
      `Neptunus.Config.TLS`); `max_connections` nil: derived from the descriptor limit;
    * `send_timeout_ms` — a send to a client that has not read for this long closes the
      connection;
    * `header_timeout_ms` — the most time a client has to send a request's head;
    * `idle_timeout_ms` — a WebSocket silent this long is closed;
    * `pilot_frames_per_s` — a piloting connection runs at `:high` while it sends at most
      this many frames per second (`NeptunusWeb.Socket.FlowControl`);
    * `backlog` — a connection with this many waiting messages drops stale telemetry;
    * `unsent_bytes` — the most of a connection's frames the kernel holds unsent (Linux,
      `TCP_NOTSENT_LOWAT`), nil: the kernel's own;
    * `auth` — `t:NeptunusWeb.Auth.config/0`;
    * `recording_dir` — the recordings the API lists and exports, nil: recording is off;
    * `firmware_record` — on an SD-card image, the file of its last firmware update
      (`Neptunus.FirmwareRecord`, `NEPTUNUS_FIRMWARE_RECORD`), nil elsewhere.
  """
  @type t :: %__MODULE__{
          port: :inet.port_number(),
          bind: :inet.ip_address(),
          tls: %{certfile: Path.t(), keyfile: Path.t()} | nil,
          max_connections: pos_integer() | nil,
          send_timeout_ms: pos_integer(),
          header_timeout_ms: pos_integer(),
          idle_timeout_ms: pos_integer(),
          pilot_frames_per_s: pos_integer(),
          backlog: pos_integer(),
          unsent_bytes: pos_integer() | nil,
          auth: NeptunusWeb.Auth.config(),
          recording_dir: Path.t() | nil,
          firmware_record: Path.t() | nil
        }

  @key {__MODULE__, :settings}

  @doc "Stores `settings` for every connection to read (the endpoint, at its start)."
  @spec put(t()) :: :ok
  def put(%__MODULE__{} = settings), do: :persistent_term.put(@key, settings)

  @doc "The settings stored by the endpoint; raises if the endpoint has never started."
  @spec get() :: t()
  def get do
    case :persistent_term.get(@key, nil) do
      %__MODULE__{} = settings ->
        settings

      nil ->
        raise ArgumentError,
              "the web settings are not set: NeptunusWeb.Endpoint stores them when it starts"
    end
  end

  @doc """
  The directory of this node's recordings (nil: recording is off), from the stored settings:
  where `Neptunus.Recording.Pull` finds them on each node.
  """
  @spec recording_dir() :: Path.t() | nil
  def recording_dir, do: get().recording_dir

  @doc """
  The URL the endpoint serves on (a wildcard bind address is named by its loopback).

      iex> settings = Neptunus.Config.Endpoint.web_settings!(endpoint: %{port: 4000, bind: {0, 0, 0, 0}})
      iex> NeptunusWeb.Endpoint.Settings.url(settings)
      "http://127.0.0.1:4000"
  """
  @spec url(t()) :: String.t()
  def url(%__MODULE__{port: port, bind: bind} = settings) do
    host =
      case bind do
        {0, 0, 0, 0} -> "127.0.0.1"
        {0, 0, 0, 0, 0, 0, 0, 0} -> "[::1]"
        {_, _, _, _} -> :inet.ntoa(bind)
        _ -> "[#{:inet.ntoa(bind)}]"
      end

    "#{scheme(settings)}://#{host}:#{port}"
  end

  @doc "`\"https\"` when the endpoint serves TLS, else `\"http\"`."
  @spec scheme(t()) :: String.t()
  def scheme(%__MODULE__{tls: nil}), do: "http"
  def scheme(%__MODULE__{}), do: "https"
end
