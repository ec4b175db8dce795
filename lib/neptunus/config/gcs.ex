defmodule Neptunus.Config.GCS do
  @moduledoc """
  The MAVLink endpoint for ground stations (`config :neptunus, :gcs`, see `Neptunus.GCS`
  and docs/MAVLINK.md): QGroundControl, Cockpit, MAVProxy and pymavlink scripts see and fly
  the node's vehicles.

  | variable                      | meaning                                                | default |
  |-------------------------------|--------------------------------------------------------|---------|
  | `NEPTUNUS_MAVLINK_SERVE`      | endpoints, comma-separated: `udpin:ADDRESS:PORT` (ground stations send first; each source address is one), `udpout:HOST:PORT[@GCS]` (push to a ground station, as a vehicle does to port 14550), `tcpin:ADDRESS:PORT` (listen for connections, 5760-style) | none: off |
  | `NEPTUNUS_MAVLINK_SYSIDS`     | each vehicle's MAVLink system id, `id=N` pairs (1..254) | 1, 2, … in `NEPTUNUS_VEHICLES` order, skipping configured ones |
  | `NEPTUNUS_MAVLINK_GCS`        | ground stations' signing keys, `name:role:KEY,...`; KEY is the 32-byte secret key in 64 hex digits (the SHA-256 of the passphrase a ground station is given) | none |
  | `NEPTUNUS_MAVLINK_GCS_FILE`   | the same in a file, lines `name role KEY` (`#` comments) | none |
  | `NEPTUNUS_MAVLINK_TRUSTED`    | system ids of ground stations that may take a free helm without asking (local mode, loopback endpoints) | none |
  | `NEPTUNUS_MAVLINK_UNSIGNED`   | what an unsigned ground station gets on an endpoint beyond loopback: `none` (nothing) or `watch` (telemetry; its own messages are still dropped) | `none` |

  Roles are the browsers' (`pilot`, `observer`, `main_station`, at most one main station
  among the keys). **An endpoint that is not on loopback needs signing**: the node refuses to
  start with one unless keys are configured, and a `udpout` beyond loopback must name the
  ground station whose key signs what it pushes (`udpout:10.0.0.5:14550@topside`).
  """

  require Logger

  alias Neptunus.Config
  alias Neptunus.Config.Auth

  @roles %{"pilot" => :pilot, "observer" => :observer, "main_station" => :main_station}

  @type endpoint :: %{
          kind: :udpin | :udpout | :tcpin,
          address: :inet.ip_address(),
          port: :inet.port_number(),
          loopback: boolean(),
          gcs: String.t() | nil,
          spec: String.t(),
          link_id: byte()
        }
  @type key :: %{name: String.t(), role: :pilot | :observer | :main_station, key: <<_::256>>}
  @type t :: %{
          endpoints: [endpoint()],
          systems: %{String.t() => 1..254},
          keys: %{String.t() => key()},
          trusted: [1..255],
          unsigned: :none | :watch,
          mode: :local | :secure
        }

  @doc """
  The ground stations' endpoint from the environment, for the node's `vehicles` (as
  `Neptunus.Config.Vehicles.vehicles!/1` gives them) and its `auth` mode (`:local` or
  `:secure`, `Neptunus.Config.Auth`). Raises `ArgumentError` naming the variable.

      iex> Neptunus.Config.GCS.gcs!(%{}, [%{id: "a"}], :local).endpoints
      []
      iex> gcs = Neptunus.Config.GCS.gcs!(%{"NEPTUNUS_MAVLINK_SERVE" => "udpin:127.0.0.1:14550"},
      ...>   [%{id: "a"}, %{id: "b"}], :local)
      iex> {hd(gcs.endpoints).kind, hd(gcs.endpoints).port, gcs.systems}
      {:udpin, 14550, %{"a" => 1, "b" => 2}}
  """
  @spec gcs!(Config.env(), [%{id: String.t()}], :local | :secure) :: t()
  def gcs!(env, vehicles, mode) do
    keys = keys!(env)
    endpoints = endpoints!(Map.get(env, "NEPTUNUS_MAVLINK_SERVE", ""), keys)

    %{
      endpoints: endpoints,
      systems: systems!(Map.get(env, "NEPTUNUS_MAVLINK_SYSIDS", ""), vehicles),
      keys: keys,
      trusted: trusted!(Map.get(env, "NEPTUNUS_MAVLINK_TRUSTED", "")),
      unsigned: unsigned!(Map.get(env, "NEPTUNUS_MAVLINK_UNSIGNED", "none")),
      mode: mode
    }
  end

  # --- endpoints ------------------------------------------------------------------------------

  defp endpoints!(spec, keys) do
    case String.trim(spec) do
      off when off in ["", "off", "none"] ->
        []

      spec ->
        endpoints =
          spec
          |> String.split(",")
          |> Enum.map(&String.trim/1)
          |> Enum.with_index()
          |> Enum.map(fn {one, i} -> endpoint!(one, i, keys) end)

        if length(endpoints) > 32,
          do: Config.bad!("NEPTUNUS_MAVLINK_SERVE", spec, "at most 32 endpoints")

        wheres = Enum.map(endpoints, &{&1.kind, &1.address, &1.port})

        if length(Enum.uniq(wheres)) != length(wheres),
          do: Config.bad!("NEPTUNUS_MAVLINK_SERVE", spec, "each endpoint once")

        endpoints
    end
  end

  defp endpoint!(spec, link_id, keys) do
    case parse_endpoint(spec) do
      {:ok, kind, host, port, gcs} ->
        address = address!(spec, kind, host)
        loopback = Auth.loopback?(address)

        endpoint = %{
          kind: kind,
          address: address,
          port: port,
          loopback: loopback,
          gcs: gcs,
          spec: spec,
          link_id: link_id
        }

        check_signing!(endpoint, keys)

      {:error, expected} ->
        Config.bad!("NEPTUNUS_MAVLINK_SERVE", spec, expected)
    end
  end

  @endpoint_shape "udpin:ADDRESS:PORT, udpout:HOST:PORT[@GCS] or tcpin:ADDRESS:PORT"

  defp parse_endpoint(spec) do
    {spec, gcs} =
      case String.split(spec, "@", parts: 2) do
        [spec, gcs] -> {spec, gcs}
        [spec] -> {spec, nil}
      end

    with [kind, rest] <- String.split(spec, ":", parts: 2),
         {:ok, kind} <- kind(kind),
         [_, host, port] <- Regex.run(~r/^\[?([^\[\]\s@]+?)\]?:([0-9]+)$/, rest),
         {port, ""} when port in 1..65_535 <- Integer.parse(port) do
      cond do
        gcs != nil and kind != :udpout ->
          {:error, "@GCS only after a udpout endpoint (#{@endpoint_shape})"}

        gcs == "" ->
          {:error, "a ground station's name after @"}

        true ->
          {:ok, kind, host, port, gcs}
      end
    else
      {:error, _} = error -> error
      {_port, _} -> {:error, "a port in 1..65535"}
      _ -> {:error, @endpoint_shape}
    end
  end

  defp kind("udpin"), do: {:ok, :udpin}
  defp kind("udpout"), do: {:ok, :udpout}
  defp kind("tcpin"), do: {:ok, :tcpin}
  defp kind(_), do: {:error, @endpoint_shape}

  # a listening endpoint binds an address; a udpout may name its ground station's host
  defp address!(spec, kind, host) do
    case :inet.parse_address(String.to_charlist(host)) do
      {:ok, address} ->
        address

      {:error, _} when kind == :udpout ->
        case :inet.getaddr(String.to_charlist(host), :inet) do
          {:ok, address} ->
            address

          {:error, reason} ->
            Config.bad!(
              "NEPTUNUS_MAVLINK_SERVE",
              spec,
              "a host that resolves (#{:inet.format_error(reason)})"
            )
        end

      {:error, _} ->
        Config.bad!("NEPTUNUS_MAVLINK_SERVE", spec, "an IP address to listen on, e.g. 0.0.0.0")
    end
  end

  defp check_signing!(%{loopback: true, gcs: nil} = endpoint, _keys), do: endpoint

  defp check_signing!(%{gcs: nil} = endpoint, keys) when keys == %{} do
    raise ArgumentError,
          "NEPTUNUS_MAVLINK_SERVE=#{endpoint.spec} serves ground stations beyond this computer, " <>
            "and nobody there may see or fly a vehicle without a signing key: set " <>
            "NEPTUNUS_MAVLINK_GCS=name:role:KEY (KEY: 64 hex digits, e.g. the output of " <>
            "`printf %s 'PASSPHRASE' | sha256sum` for the passphrase the ground station is " <>
            "given) or NEPTUNUS_MAVLINK_GCS_FILE, or serve on 127.0.0.1"
  end

  defp check_signing!(%{kind: :udpout, loopback: false, gcs: nil} = endpoint, _keys) do
    Config.bad!(
      "NEPTUNUS_MAVLINK_SERVE",
      endpoint.spec,
      "udpout:HOST:PORT@GCS beyond loopback: the ground station (of NEPTUNUS_MAVLINK_GCS) " <>
        "whose key signs what it pushes"
    )
  end

  defp check_signing!(%{gcs: nil} = endpoint, _keys), do: endpoint

  defp check_signing!(%{gcs: gcs} = endpoint, keys) do
    if Map.has_key?(keys, gcs),
      do: endpoint,
      else:
        Config.bad!(
          "NEPTUNUS_MAVLINK_SERVE",
          endpoint.spec,
          "@GCS naming a ground station of NEPTUNUS_MAVLINK_GCS (#{inspect(Map.keys(keys))})"
        )
  end

  # --- system ids -----------------------------------------------------------------------------

  defp systems!(spec, vehicles) do
    ids = Enum.map(vehicles, & &1.id)

    configured =
      spec
      |> String.split(",", trim: true)
      |> Enum.map(&String.trim/1)
      |> Enum.reject(&(&1 == ""))
      |> Map.new(fn pair ->
        case String.split(pair, "=", parts: 2) do
          [id, n] ->
            unless id in ids,
              do:
                Config.bad!("NEPTUNUS_MAVLINK_SYSIDS", pair, "id=N with id a configured vehicle")

            case Integer.parse(n) do
              {n, ""} when n in 1..254 -> {id, n}
              _ -> Config.bad!("NEPTUNUS_MAVLINK_SYSIDS", pair, "id=N with N in 1..254")
            end

          _ ->
            Config.bad!("NEPTUNUS_MAVLINK_SYSIDS", pair, "id=N with N in 1..254")
        end
      end)

    taken = Map.values(configured)

    if length(Enum.uniq(taken)) != length(taken),
      do: Config.bad!("NEPTUNUS_MAVLINK_SYSIDS", spec, "a different system id for each vehicle")

    {systems, _} =
      Enum.reduce(ids, {configured, 1}, fn id, {acc, next} ->
        if Map.has_key?(acc, id) do
          {acc, next}
        else
          n = Enum.find(next..254, &(&1 not in taken))

          if n == nil,
            do: Config.bad!("NEPTUNUS_MAVLINK_SYSIDS", spec, "at most 254 vehicles")

          {Map.put(acc, id, n), n + 1}
        end
      end)

    systems
  end

  # --- keys -----------------------------------------------------------------------------------

  @doc """
  The warning for a keys file whose permission bits `mode` let its group or others read or
  write it (whoever reads a key can sign as that ground station), or nil.

      iex> Neptunus.Config.GCS.keys_file_warning("/etc/neptunus/gcs-keys", 0o100600)
      nil
      iex> Neptunus.Config.GCS.keys_file_warning("/etc/neptunus/gcs-keys", 0o100640)
      "NEPTUNUS_MAVLINK_GCS_FILE /etc/neptunus/gcs-keys is open to its group (mode 640): " <>
        "whoever reads it can sign as its ground stations; run `chmod 600 /etc/neptunus/gcs-keys`"
  """
  @spec keys_file_warning(String.t(), non_neg_integer()) :: String.t() | nil
  def keys_file_warning(path, mode) do
    bits = Bitwise.band(mode, 0o777)

    who =
      cond do
        Bitwise.band(bits, 0o007) != 0 -> "others"
        Bitwise.band(bits, 0o070) != 0 -> "its group"
        true -> nil
      end

    if who,
      do:
        "NEPTUNUS_MAVLINK_GCS_FILE #{path} is open to #{who} (mode #{Integer.to_string(bits, 8)}): " <>
          "whoever reads it can sign as its ground stations; run `chmod 600 #{path}`"
  end

  defp keys!(env) do
    inline =
      env
      |> Map.get("NEPTUNUS_MAVLINK_GCS", "")
      |> String.split(",", trim: true)
      |> Enum.map(&String.trim/1)
      |> Enum.reject(&(&1 == ""))
      |> Enum.map(&key!(String.split(&1, ":"), "NEPTUNUS_MAVLINK_GCS", &1))

    from_file =
      for {words, where} <- Config.file_entries!(env, "NEPTUNUS_MAVLINK_GCS_FILE"),
          do: key!(words, "NEPTUNUS_MAVLINK_GCS_FILE", where)

    with path when path != "" <- Map.get(env, "NEPTUNUS_MAVLINK_GCS_FILE", ""),
         {:ok, %File.Stat{mode: mode}} <- File.stat(path),
         warning when is_binary(warning) <- keys_file_warning(path, mode),
         do: Logger.warning(warning)

    keys = inline ++ from_file
    names = Enum.map(keys, & &1.name)

    if length(Enum.uniq(names)) != length(names),
      do: Config.bad!("NEPTUNUS_MAVLINK_GCS", Enum.join(names, ","), "each ground station once")

    if Enum.count(keys, &(&1.role == :main_station)) > 1,
      do:
        Config.bad!(
          "NEPTUNUS_MAVLINK_GCS",
          Enum.join(names, ","),
          "at most one main_station"
        )

    secrets = Enum.map(keys, & &1.key)

    if length(Enum.uniq(secrets)) != length(secrets),
      do:
        Config.bad!(
          "NEPTUNUS_MAVLINK_GCS",
          Enum.join(names, ","),
          "a different key for each ground station (a key names who signs)"
        )

    Map.new(keys, &{&1.name, &1})
  end

  defp key!([name, role, hex], variable, where) do
    cond do
      not Regex.match?(~r/^[A-Za-z0-9_.-]{1,32}$/, name) ->
        Config.bad!(variable, where, "a name of 1..32 characters of A-Z a-z 0-9 _ . -")

      not Map.has_key?(@roles, role) ->
        Config.bad!(variable, where, "a role: pilot, observer or main_station")

      true ->
        case Base.decode16(hex, case: :mixed) do
          {:ok, <<_::256>> = key} -> %{name: name, role: Map.fetch!(@roles, role), key: key}
          _ -> Config.bad!(variable, where, "a key of 64 hex digits (32 bytes)")
        end
    end
  end

  defp key!(_parts, variable, where),
    do: Config.bad!(variable, where, "name, role and key (64 hex digits)")

  # --- the rest -------------------------------------------------------------------------------

  defp trusted!(spec) do
    spec
    |> String.split(",", trim: true)
    |> Enum.map(&String.trim/1)
    |> Enum.reject(&(&1 == ""))
    |> Enum.map(fn n ->
      case Integer.parse(n) do
        {n, ""} when n in 1..255 -> n
        _ -> Config.bad!("NEPTUNUS_MAVLINK_TRUSTED", n, "system ids in 1..255")
      end
    end)
    |> Enum.uniq()
  end

  defp unsigned!(value) do
    case String.trim(value) do
      "none" -> :none
      "watch" -> :watch
      other -> Config.bad!("NEPTUNUS_MAVLINK_UNSIGNED", other, "none or watch")
    end
  end
end
