defmodule Neptunus.Config.Endpoint do
  @moduledoc """
  Where the node listens (`config :neptunus, :endpoint`, see `NeptunusWeb.Endpoint`):
  `NEPTUNUS_PORT` (TCP port for HTTP and WebSocket, default 4000), `NEPTUNUS_BIND` (IPv4/IPv6
  address, default `127.0.0.1`) and `NEPTUNUS_MAX_CONNECTIONS` (client connections at once,
  1..1048576; unset: derived from the file descriptor limit).
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
