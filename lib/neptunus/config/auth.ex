defmodule Neptunus.Config.Auth do
  @moduledoc """
  Login and connection security (`config :neptunus, :auth`, see `NeptunusWeb.Auth`):

  | variable                       | meaning                                             | default        |
  |--------------------------------|-----------------------------------------------------|----------------|
  | `NEPTUNUS_SECRET`              | token signing secret, ≥ 32 characters               | none: local mode on loopback |
  | `NEPTUNUS_USERS_FILE`          | users file, lines `name role hash`                  | none           |
  | `NEPTUNUS_USERS`               | users inline, `name:role:hash,...`                  | none           |
  | `NEPTUNUS_ANONYMOUS_OBSERVERS` | connections without login may watch                 | `false`        |
  | `NEPTUNUS_ORIGINS`             | allowed browser origins, comma-separated            | same origin    |
  | `NEPTUNUS_TOKEN_TTL_S`         | login token lifetime (s)                            | 43200          |
  | `NEPTUNUS_LOGIN_ATTEMPTS`      | login attempts per minute per address               | 10             |

  Roles: `pilot`, `observer`, `main_station` (at most one). A bind address other than
  loopback without a secret and users stops the node with a message saying what to set.
  """

  require Logger

  alias Neptunus.Config

  @doc """
  Login and connection security (`config :neptunus, :auth`, see `NeptunusWeb.Auth`) from the
  environment, for the `endpoint` it protects.

  Secure by default: bound to a loopback address with neither `NEPTUNUS_SECRET` nor users,
  the node runs in *local mode* (no logins; anyone on this computer may pilot). Any other
  bind address needs a secret and users, and so does a configuration that has one of them.

      iex> Neptunus.Config.Auth.auth!(%{}, %{bind: {127, 0, 0, 1}}).mode
      :local
  """
  @spec auth!(Config.env(), %{bind: :inet.ip_address()}) :: map()
  def auth!(env, %{bind: bind}) do
    secret = secret!(Map.get(env, "NEPTUNUS_SECRET"))
    users = users!(env)

    settings = %{
      secret: secret,
      users: users,
      anonymous_observers: Config.env_boolean!(env, "NEPTUNUS_ANONYMOUS_OBSERVERS", false),
      origins: origins!(Map.get(env, "NEPTUNUS_ORIGINS", "")),
      token_ttl_s: Config.env_integer!(env, "NEPTUNUS_TOKEN_TTL_S", 43_200, 60..2_592_000),
      login_attempts_per_minute: Config.env_integer!(env, "NEPTUNUS_LOGIN_ATTEMPTS", 10, 1..1000)
    }

    cond do
      secret == nil and users == %{} and loopback?(bind) ->
        Map.put(settings, :mode, :local)

      secret == nil and users == %{} ->
        raise ArgumentError,
              "NEPTUNUS_BIND=#{:inet.ntoa(bind)} serves beyond this computer, and Neptunus " <>
                "lets nobody on a network pilot without logging in. Set NEPTUNUS_SECRET " <>
                "(at least 32 characters, e.g. the output of `openssl rand -base64 48`) and " <>
                "the users: NEPTUNUS_USERS_FILE=/path/to/users (lines `name role hash`) or " <>
                "NEPTUNUS_USERS=name:role:hash,... with roles pilot, observer, main_station " <>
                "(at most one) and hashes from `mix neptunus.passwd NAME ROLE`. " <>
                "Or set NEPTUNUS_BIND=127.0.0.1 for local mode."

      secret == nil ->
        raise ArgumentError,
              "users are configured (NEPTUNUS_USERS / NEPTUNUS_USERS_FILE) but NEPTUNUS_SECRET " <>
                "is not set: set it to at least 32 random characters (e.g. the output of " <>
                "`openssl rand -base64 48`) to sign login tokens"

      users == %{} ->
        raise ArgumentError,
              "NEPTUNUS_SECRET is set but there are no users, so nobody could log in: set " <>
                "NEPTUNUS_USERS_FILE (lines `name role hash`) or NEPTUNUS_USERS " <>
                "(name:role:hash,...); hashes from `mix neptunus.passwd NAME ROLE`"

      true ->
        Map.put(settings, :mode, :secure)
    end
  end

  @doc """
  Local mode with every default: what `auth!/2` gives for an empty environment on a
  loopback address (the settings `Neptunus.Config.Endpoint.web_settings!/1` starts from).

      iex> Neptunus.Config.Auth.local().token_ttl_s
      43200
  """
  @spec local() :: map()
  def local, do: auth!(%{}, %{bind: {127, 0, 0, 1}})

  @doc """
  Whether `address` is a loopback address (127.0.0.0/8 or ::1): reachable from this computer
  only. The one loopback test of the node (local mode, the endpoint's TLS warning, the
  `Host` check of local mode).

      iex> Neptunus.Config.Auth.loopback?({127, 0, 1, 1})
      true
      iex> Neptunus.Config.Auth.loopback?({0, 0, 0, 0, 0, 0, 0, 1})
      true
      iex> Neptunus.Config.Auth.loopback?({0, 0, 0, 0})
      false
  """
  @spec loopback?(:inet.ip_address()) :: boolean()
  def loopback?({127, _, _, _}), do: true
  def loopback?({0, 0, 0, 0, 0, 0, 0, 1}), do: true
  def loopback?(_), do: false

  defp secret!(nil), do: nil
  defp secret!(""), do: nil

  defp secret!(secret) do
    if byte_size(secret) >= 32,
      do: secret,
      else:
        Config.bad!(
          "NEPTUNUS_SECRET",
          "(#{byte_size(secret)} characters)",
          "at least 32 characters, e.g. the output of `openssl rand -base64 48`"
        )
  end

  defp users!(env) do
    from_file =
      for {words, where} <- Config.file_entries!(env, "NEPTUNUS_USERS_FILE"),
          do: user!(words, "NEPTUNUS_USERS_FILE", where)

    with path when path != "" <- Map.get(env, "NEPTUNUS_USERS_FILE", ""),
         do: warn_users_file(path)

    inline =
      env
      |> Map.get("NEPTUNUS_USERS", "")
      |> String.split(",", trim: true)
      |> Enum.map(&String.trim/1)
      |> Enum.reject(&(&1 == ""))
      |> Enum.map(&user!(String.split(&1, ":"), "NEPTUNUS_USERS", &1))

    users = from_file ++ inline
    names = Enum.map(users, & &1.name)

    case names -- Enum.uniq(names) do
      [] ->
        :ok

      [dup | _] ->
        Config.bad!("NEPTUNUS_USERS", dup, "unique user names (#{dup} is defined twice)")
    end

    case Enum.filter(users, &(&1.role == :main_station)) do
      [_, _ | _] = mains ->
        Config.bad!(
          "NEPTUNUS_USERS",
          Enum.map_join(mains, ",", & &1.name),
          "at most one main_station"
        )

      _ ->
        :ok
    end

    Map.new(users, &{&1.name, &1})
  end

  defp warn_users_file(path) do
    case File.stat(path) do
      {:ok, %File.Stat{mode: mode}} ->
        case users_file_warning(path, mode) do
          nil -> :ok
          warning -> Logger.warning(warning)
        end

      {:error, _} ->
        :ok
    end
  end

  @doc """
  The warning for a users file whose permission bits `mode` let its group or others read
  or write it (the password hashes can be attacked offline by whoever reads them), or nil.

      iex> Neptunus.Config.Auth.users_file_warning("/etc/neptunus/users", 0o100600)
      nil
      iex> Neptunus.Config.Auth.users_file_warning("/etc/neptunus/users", 0o100644)
      "NEPTUNUS_USERS_FILE /etc/neptunus/users is open to others (mode 644): its password " <>
        "hashes can be attacked offline; run `chmod 600 /etc/neptunus/users`"
  """
  @spec users_file_warning(String.t(), non_neg_integer()) :: String.t() | nil
  def users_file_warning(path, mode) do
    bits = Bitwise.band(mode, 0o777)

    if Bitwise.band(bits, 0o077) == 0 do
      nil
    else
      who = if Bitwise.band(bits, 0o007) != 0, do: "others", else: "its group"

      "NEPTUNUS_USERS_FILE #{path} is open to #{who} (mode #{Integer.to_string(bits, 8)}): " <>
        "its password hashes can be attacked offline; run `chmod 600 #{path}`"
    end
  end

  @roles %{"pilot" => :pilot, "observer" => :observer, "main_station" => :main_station}

  defp user!([name, role, hash], variable, where) do
    cond do
      not Regex.match?(~r/^[A-Za-z0-9_.@-]{1,40}$/, name) ->
        Config.bad!(variable, where, "user names of 1..40 characters a-z A-Z 0-9 _ . @ -")

      not Map.has_key?(@roles, role) ->
        Config.bad!(
          variable,
          where,
          "a role: pilot, observer or main_station (got #{inspect(role)})"
        )

      match?({:error, _}, NeptunusWeb.Auth.Password.parse(hash)) ->
        Config.bad!(variable, where, "a password hash from `mix neptunus.passwd NAME ROLE`")

      true ->
        %{name: name, role: Map.fetch!(@roles, role), hash: hash}
    end
  end

  defp user!(_fields, "NEPTUNUS_USERS", where),
    do: Config.bad!("NEPTUNUS_USERS", where, "name:role:hash entries separated by commas")

  defp user!(_fields, variable, where),
    do: Config.bad!(variable, where, "lines `name role hash`")

  defp origins!(spec) do
    spec
    |> String.split(",", trim: true)
    |> Enum.map(&String.trim/1)
    |> Enum.reject(&(&1 == ""))
    |> Enum.map(fn origin ->
      case URI.parse(origin) do
        %URI{scheme: scheme, host: host, path: path, query: nil}
        when scheme in ["http", "https"] and is_binary(host) and host != "" and path in [nil, "/"] ->
          origin |> String.trim_trailing("/") |> String.downcase()

        _ ->
          Config.bad!(
            "NEPTUNUS_ORIGINS",
            spec,
            "origins like https://rov.example.org or http://10.0.0.2:4000"
          )
      end
    end)
  end
end
