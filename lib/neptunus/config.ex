defmodule Neptunus.Config do
  @moduledoc """
  Parses and validates the node's environment variables (read by `config/runtime.exs`).

  Every function either returns a validated value or raises `ArgumentError` with a message
  that names the variable, the bad value and what a good one looks like, so a typo stops the
  node at boot instead of starting something the operator did not ask for.

  | variable            | meaning                                  | default                |
  |---------------------|------------------------------------------|------------------------|
  | `NEPTUNUS_PORT`     | TCP port for HTTP and WebSocket          | 4000                   |
  | `NEPTUNUS_BIND`     | IPv4/IPv6 address to listen on           | `127.0.0.1`            |
  | `NEPTUNUS_VEHICLES` | comma-separated `id=board` pairs         | `neptunus-1=simulated` |

  Boards known today: `simulated`. Vehicle ids are 1..32 characters of `a-z A-Z 0-9 _ -`.
  """

  @type endpoint :: %{port: :inet.port_number(), bind: :inet.ip_address()}
  @type vehicle :: %{id: String.t(), board: :simulated}

  @default_vehicles "neptunus-1=simulated"
  @boards %{"simulated" => :simulated}

  @doc """
  Endpoint settings from the environment map.

      iex> Neptunus.Config.endpoint!(%{}, 4000)
      %{port: 4000, bind: {127, 0, 0, 1}}

      iex> Neptunus.Config.endpoint!(%{"NEPTUNUS_PORT" => "8080", "NEPTUNUS_BIND" => "0.0.0.0"}, 4000)
      %{port: 8080, bind: {0, 0, 0, 0}}
  """
  @spec endpoint!(%{optional(String.t()) => String.t()}, :inet.port_number()) :: endpoint()
  def endpoint!(env, default_port) do
    %{
      port: port!(Map.get(env, "NEPTUNUS_PORT"), default_port),
      bind: bind!(Map.get(env, "NEPTUNUS_BIND", "127.0.0.1"))
    }
  end

  @doc """
  Vehicles from `NEPTUNUS_VEHICLES`.

      iex> Neptunus.Config.vehicles!(%{"NEPTUNUS_VEHICLES" => "a=simulated, b=simulated"})
      [%{id: "a", board: :simulated}, %{id: "b", board: :simulated}]
  """
  @spec vehicles!(%{optional(String.t()) => String.t()}) :: [vehicle()]
  def vehicles!(env) do
    spec = Map.get(env, "NEPTUNUS_VEHICLES", @default_vehicles)

    vehicles =
      spec
      |> String.split(",")
      |> Enum.map(&String.trim/1)
      |> Enum.map(&vehicle!(&1, spec))

    if vehicles == [] or spec |> String.trim() == "" do
      bad!("NEPTUNUS_VEHICLES", spec, "at least one vehicle, e.g. #{@default_vehicles}")
    end

    ids = Enum.map(vehicles, & &1.id)

    case ids -- Enum.uniq(ids) do
      [] -> vehicles
      [dup | _] -> bad!("NEPTUNUS_VEHICLES", spec, "unique vehicle ids (#{inspect(dup)} repeats)")
    end
  end

  defp vehicle!(pair, spec) do
    with [id, board] <- String.split(pair, "=", parts: 2),
         id = String.trim(id),
         true <- Regex.match?(~r/^[A-Za-z0-9_-]{1,32}$/, id) || {:bad_id, id},
         {:ok, board} <- Map.fetch(@boards, String.trim(board)) do
      %{id: id, board: board}
    else
      {:bad_id, id} ->
        bad!(
          "NEPTUNUS_VEHICLES",
          spec,
          "vehicle ids of 1..32 characters a-z A-Z 0-9 _ - (got #{inspect(id)})"
        )

      :error ->
        bad!(
          "NEPTUNUS_VEHICLES",
          spec,
          "a known board in #{inspect(pair)}: one of #{Enum.join(Map.keys(@boards), ", ")}"
        )

      _ ->
        bad!("NEPTUNUS_VEHICLES", spec, "id=board pairs separated by commas, e.g. rov=simulated")
    end
  end

  defp port!(nil, default), do: default

  defp port!(value, _default) do
    case Integer.parse(String.trim(value)) do
      {port, ""} when port in 1..65_535 -> port
      _ -> bad!("NEPTUNUS_PORT", value, "a TCP port number 1..65535")
    end
  end

  defp bind!(value) do
    case :inet.parse_address(String.to_charlist(String.trim(value))) do
      {:ok, address} -> address
      {:error, _} -> bad!("NEPTUNUS_BIND", value, "an IP address such as 127.0.0.1 or 0.0.0.0")
    end
  end

  defp bad!(variable, value, expected) do
    raise ArgumentError, "#{variable}=#{inspect(value)} is not valid: expected #{expected}"
  end
end
