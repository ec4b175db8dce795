defmodule NeptunusWeb.Auth do
  @moduledoc """
  Who may connect, and as whom.

  ## Modes

    * **local** — the server listens on a loopback address and no secret is configured
      (`Neptunus.Config.Auth.auth!/2` allows nothing else without a secret). No logins: every
      connection is a `pilot` named by its `name` parameter, and the pages show a banner
      saying so. Every HTTP request — pages, assets, the API, the camera, WebSocket
      upgrades — must name a loopback host (`Host: localhost`, `127.x.x.x`, `[::1]`;
      `check_host/2`, applied by `NeptunusWeb.Endpoint.Guard`), so a web page on another site
      cannot reach the vehicle or its recordings through the operator's browser, not even by
      DNS rebinding.
    * **secure** — users with roles `pilot`, `observer` and at most one `main_station` log in
      with `POST /api/login` and get a signed, expiring token (`NeptunusWeb.Auth.Token`),
      passed to the WebSocket as the `token` query parameter. Connections without a token
      are refused, unless anonymous observers are allowed (they are `observer`s named
      `guest-XXXX`).

  In both modes a WebSocket upgrade whose `Origin` is not allowed is refused (cross-site
  WebSocket hijacking): allowed are the configured origins (`NEPTUNUS_ORIGINS`) or, when none
  are configured, the server's own origin (the `Origin` names the scheme the server serves
  and the `Host` the request was sent to). In secure mode with configured origins every HTTP
  request's `Host` must be one of their hosts. Requests without `Origin` come from programs, not browsers, and are let through
  to the token check.

  ## Configuration (`config :neptunus, :auth`, built by `Neptunus.Config.Auth.auth!/2`)

      %{mode: :local | :secure, secret: binary | nil,
        users: %{name => %{name, role, hash}}, anonymous_observers: boolean,
        origins: [String.t()], token_ttl_s: pos_integer, login_attempts_per_minute: pos_integer}

  It is read once at boot into the web settings (`NeptunusWeb.Endpoint.Settings`, `auth`),
  which every connection and login reads.
  """

  alias NeptunusWeb.Auth.{Password, RateLimit, Token}
  alias NeptunusWeb.Endpoint.Settings

  @type role :: :pilot | :observer | :main_station
  @type user :: %{id: String.t(), name: String.t(), role: role()}
  @type config :: %{
          mode: :local | :secure,
          secret: binary() | nil,
          users: %{optional(String.t()) => %{name: String.t(), role: role(), hash: String.t()}},
          anonymous_observers: boolean(),
          origins: [String.t()],
          token_ttl_s: pos_integer(),
          login_attempts_per_minute: pos_integer()
        }

  @doc "The configuration, from the web settings (`NeptunusWeb.Endpoint.Settings`)."
  @spec config() :: config()
  def config, do: Settings.get().auth

  @doc "`:local` or `:secure`."
  @spec mode() :: :local | :secure
  def mode, do: config().mode

  @doc """
  Decides a WebSocket upgrade. `request` has `origin` and `host` (header values or nil),
  `token` and `name` (query parameters or nil). Returns the connection's user, or the HTTP
  status and reason to refuse it with.
  """
  @spec connect(%{origin: String.t() | nil, host: String.t() | nil, token: term(), name: term()}) ::
          {:ok, user()} | {:error, 401 | 403, String.t()}
  def connect(request) do
    config = config()

    with :ok <- check_origin(request.origin, request.host, config.origins),
         :ok <- check_host(config, request.host) do
      user(config, request)
    end
  end

  defp user(%{mode: :local}, %{name: name}),
    do: {:ok, %{id: conn_id(), name: display_name(name), role: :pilot}}

  defp user(config, %{token: token}) when is_binary(token) and token != "" do
    with {:ok, claims} <- Token.verify(token, config.secret, now_s()),
         {:ok, %{name: name, role: role}} <- lookup(config, claims.name) do
      {:ok, %{id: conn_id(), name: name, role: role}}
    else
      {:error, reason} -> {:error, 401, reason}
    end
  end

  defp user(%{anonymous_observers: true}, _request),
    do: {:ok, %{id: conn_id(), name: guest_name(), role: :observer}}

  defp user(_config, _request),
    do: {:error, 401, "login required: no token (log in at /login.html)"}

  defp lookup(config, name) do
    case Map.fetch(config.users, name) do
      {:ok, user} -> {:ok, user}
      :error -> {:error, "unknown user: #{name}"}
    end
  end

  @doc """
  Checks a login for `name` and `password` from `address`. Returns the token and who it is
  for, or the HTTP status and reason: 400 (local mode), 401 (wrong name or password — the
  same reason for both), 429 (too many attempts from this address, with the seconds to
  wait).
  """
  @spec login(term(), term(), term()) ::
          {:ok, %{token: String.t(), expires_at: integer(), user: map()}}
          | {:error, 400 | 401, String.t()}
          | {:error, 429, String.t(), pos_integer()}
  def login(name, password, address) do
    config = config()

    cond do
      config.mode == :local ->
        {:error, 400,
         "this server runs in local mode and needs no login " <>
           "(set NEPTUNUS_SECRET and users to require one)"}

      not (is_binary(name) and is_binary(password)) ->
        {:error, 400, "name and password must be strings"}

      true ->
        case RateLimit.check(address, config.login_attempts_per_minute) do
          :ok -> check_password(config, name, password)
          {:error, retry_ms} -> too_many(retry_ms)
        end
    end
  end

  defp check_password(config, name, password) do
    user = Map.get(config.users, name)
    ok? = Password.check(password, user && user.hash, login_iterations(config))

    if ok? do
      now = now_s()
      token = Token.sign(user.name, config.secret, now, config.token_ttl_s)

      {:ok,
       %{
         token: token,
         expires_at: (now + config.token_ttl_s) * 1000,
         user: %{name: user.name, role: Atom.to_string(user.role)}
       }}
    else
      {:error, 401, "wrong name or password"}
    end
  end

  @doc """
  What every password check costs, in PBKDF2 iterations: those of the most expensive
  configured user's hash (the default of new hashes without users). Every login — an
  unknown name, a known one with a cheaper hash, a wrong password — spends exactly this
  (`NeptunusWeb.Auth.Password.check/3`), so its time does not tell which names exist.
  """
  @spec login_iterations(%{required(:users) => map(), optional(atom()) => term()}) ::
          pos_integer()
  def login_iterations(%{users: users}) do
    users
    |> Enum.map(fn {_name, user} -> Password.iterations(user.hash) end)
    |> Enum.reject(&is_nil/1)
    |> Enum.max(fn -> Password.default_iterations() end)
  end

  defp too_many(retry_ms) do
    seconds = div(retry_ms + 999, 1000)
    {:error, 429, "too many login attempts: try again in #{seconds} s", seconds}
  end

  @doc """
  What a page needs to know before it connects: the mode, whether anonymous observers are
  allowed, and who `token` (nil: none) belongs to. `{:error, reason}` for a token that is
  invalid, expired or of an unknown user.
  """
  @spec session(term()) :: {:ok, map()} | {:error, map()}
  def session(token) do
    config = config()
    base = %{mode: Atom.to_string(config.mode), anonymous_observers: config.anonymous_observers}

    cond do
      config.mode == :local ->
        {:ok, Map.merge(base, %{user: nil, expires_at: nil})}

      token in [nil, ""] ->
        {:ok, Map.merge(base, %{user: nil, expires_at: nil})}

      true ->
        with {:ok, claims} <- Token.verify(token, config.secret, now_s()),
             {:ok, user} <- lookup(config, claims.name) do
          user = %{name: user.name, role: Atom.to_string(user.role)}
          {:ok, Map.merge(base, %{user: user, expires_at: claims.expires_at * 1000})}
        else
          {:error, reason} -> {:error, Map.put(base, :error, reason)}
        end
    end
  end

  @doc """
  Whether a request from `origin` (the `Origin` header, nil if absent) to `host` (the `Host`
  header) may proceed, given the configured `origins` (empty: same origin only).

      iex> NeptunusWeb.Auth.check_origin("http://127.0.0.1:4000", "127.0.0.1:4000", [])
      :ok
      iex> NeptunusWeb.Auth.check_origin("http://evil.example", "127.0.0.1:4000", [])
      {:error, 403, "origin not allowed: http://evil.example"}
      iex> NeptunusWeb.Auth.check_origin("https://rov.example.org", "10.0.0.2", ["https://rov.example.org"])
      :ok
      iex> NeptunusWeb.Auth.check_origin(nil, "127.0.0.1:4000", [])
      :ok
  """
  @spec check_origin(String.t() | nil, String.t() | nil, [String.t()]) ::
          :ok | {:error, 403, String.t()}
  def check_origin(origin, host, origins),
    do: check_origin(origin, host, origins, server_scheme())

  @doc """
  `check_origin/3` for a server on `scheme` (`"http"` or `"https"`): without configured
  origins, the same origin means the same scheme too, so a page served over plain `http`
  (on a network path an attacker may control) cannot talk to an `https` server.

      iex> NeptunusWeb.Auth.check_origin("http://rov.local", "rov.local", [], "https")
      {:error, 403, "origin not allowed: http://rov.local"}
      iex> NeptunusWeb.Auth.check_origin("https://rov.local", "rov.local", [], "https")
      :ok
  """
  @spec check_origin(String.t() | nil, String.t() | nil, [String.t()], String.t()) ::
          :ok | {:error, 403, String.t()}
  def check_origin(nil, _host, _origins, _scheme), do: :ok

  def check_origin(origin, host, origins, server_scheme) do
    allowed? =
      case origins do
        [] -> same_origin?(origin, host, server_scheme)
        list -> normalize_origin(origin) in Enum.map(list, &normalize_origin/1)
      end

    if allowed?, do: :ok, else: {:error, 403, "origin not allowed: #{origin}"}
  end

  @doc """
  `"https"` when the endpoint serves TLS (`NeptunusWeb.Endpoint.Settings`), else `"http"`.
  """
  @spec server_scheme() :: String.t()
  def server_scheme, do: Settings.scheme(Settings.get())

  defp same_origin?(_origin, nil, _server_scheme), do: false

  defp same_origin?(origin, host, server_scheme) do
    case URI.parse(origin) do
      %URI{scheme: ^server_scheme, host: h, port: port} when is_binary(h) ->
        {host_name, host_port} = split_host(host, port)
        String.downcase(h) == host_name and port == host_port

      _ ->
        false
    end
  end

  # "example.org:8080" → {"example.org", 8080}; without a port, the origin's default port
  defp split_host(host, default_port) do
    host = String.downcase(host)

    case Regex.run(~r/^(\[[^\]]+\]|[^:]+)(?::(\d+))?$/, host) do
      [_, name] -> {String.trim(name, "[") |> String.trim("]"), default_port}
      [_, name, port] -> {String.trim(name, "[") |> String.trim("]"), String.to_integer(port)}
      nil -> {host, default_port}
    end
  end

  defp normalize_origin(origin),
    do: origin |> String.trim() |> String.trim_trailing("/") |> String.downcase()

  @doc """
  In local mode the `Host` of a WebSocket upgrade must be a loopback name.

      iex> NeptunusWeb.Auth.check_local_host(:local, "localhost:4000")
      :ok
      iex> NeptunusWeb.Auth.check_local_host(:local, "rebind.example:4000")
      {:error, 403, "host not allowed in local mode: rebind.example:4000 (use 127.0.0.1 or localhost)"}
  """
  @spec check_local_host(:local | :secure, String.t() | nil) :: :ok | {:error, 403, String.t()}
  def check_local_host(:local, host) when is_binary(host) do
    {name, _port} = split_host(host, nil)

    loopback? =
      name == "localhost" or String.ends_with?(name, ".localhost") or
        case :inet.parse_address(String.to_charlist(name)) do
          {:ok, address} -> Neptunus.Config.Auth.loopback?(address)
          {:error, _} -> false
        end

    if loopback?,
      do: :ok,
      else: {:error, 403, "host not allowed in local mode: #{host} (use 127.0.0.1 or localhost)"}
  end

  def check_local_host(:local, nil),
    do:
      {:error, 403, "host not allowed in local mode: no Host header (use 127.0.0.1 or localhost)"}

  def check_local_host(_mode, _host), do: :ok

  @doc """
  Whether an HTTP request (any: pages, assets, the API, the camera, WebSocket upgrades) to
  `host` (its `Host` header, nil if absent) may be served, against DNS rebinding: a name
  the attacker controls, first resolved to their server, then to this one, makes the
  victim's browser treat this server as the attacker's site. In local mode only loopback
  names and addresses (`check_local_host/2`); in secure mode with configured origins only
  their host names (any port: a reverse proxy may forward another one); in secure mode
  without configured origins any host (every request needs a token there anyway).

      iex> NeptunusWeb.Auth.check_host(%{mode: :local, origins: []}, "[::1]:4000")
      :ok
      iex> NeptunusWeb.Auth.check_host(%{mode: :secure, origins: ["https://rov.example.org"]}, "rov.example.org")
      :ok
      iex> NeptunusWeb.Auth.check_host(%{mode: :secure, origins: ["https://rov.example.org"]}, "rebind.example")
      {:error, 403, "host not allowed: rebind.example (allowed: rov.example.org)"}
  """
  @spec check_host(
          %{
            required(:mode) => :local | :secure,
            required(:origins) => [String.t()],
            optional(atom()) => term()
          },
          String.t() | nil
        ) ::
          :ok | {:error, 403, String.t()}
  def check_host(%{mode: :local}, host), do: check_local_host(:local, host)
  def check_host(%{origins: []}, _host), do: :ok

  def check_host(%{origins: origins}, host) do
    names =
      origins
      |> Enum.map(&(URI.parse(String.trim(&1)).host || ""))
      |> Enum.map(&String.downcase/1)

    case host && split_host(host, nil) do
      {name, _port} -> if name in names, do: :ok, else: refuse_host(host, names)
      nil -> refuse_host("(none)", names)
    end
  end

  defp refuse_host(host, names),
    do: {:error, 403, "host not allowed: #{host} (allowed: #{Enum.join(names, ", ")})"}

  @doc "A display name from the `name` parameter (trimmed, at most 40 characters) or `guest-XXXX`."
  @spec display_name(term()) :: String.t()
  def display_name(name) when is_binary(name) do
    case name |> String.trim() |> String.slice(0, 40) do
      "" -> guest_name()
      trimmed -> trimmed
    end
  end

  def display_name(_), do: guest_name()

  defp guest_name, do: "guest-" <> String.slice(conn_id(), 0, 4)

  defp conn_id, do: Base.url_encode64(:crypto.strong_rand_bytes(9), padding: false)

  # login tokens carry Unix seconds (wall clock: they outlive the node)
  defp now_s, do: div(Neptunus.Clock.wall_ms(), 1000)
end
