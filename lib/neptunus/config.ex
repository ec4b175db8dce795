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
  | `NEPTUNUS_WIRING`   | comma-separated `id=wiring` pairs        | thesis wiring          |
  | `NEPTUNUS_FIRMWARE` | comma-separated `id=firmware` pairs      | `openrov-2.5`          |
  | `NEPTUNUS_MODELS`   | comma-separated `id=model` pairs         | `neptunus`             |
  | `NEPTUNUS_CAMERAS`  | comma-separated `id=source` pairs        | none                   |
  | `NEPTUNUS_RECORDINGS` | recordings directory, or `off`         | `recordings`           |
  | `NEPTUNUS_RECORDING_MAX_MB` | one recording file's size (MiB)  | 256                    |
  | `NEPTUNUS_RECORDING_MIN_FREE_MB` | stop recording below this free disk (MiB) | 512 |
  | `NEPTUNUS_RECORDING_KEEP_DAYS` | delete recordings older than this (days), or `forever` | `forever` |
  | `NEPTUNUS_OS_SLICE_US` | OS time slice the server's threads ask for (µs, 100..100000), or `default` | 100 |
  | `NEPTUNUS_MAX_CONNECTIONS` | concurrent client connections (1..1048576); more are closed at once | from the descriptor limit |

  Boards: `simulated` (the built-in simulator), `sitl` (the simulator behind a pseudo-terminal
  speaking the OpenROV protocol, through the real board link), `uart:DEVICE[@BAUD]` (a real
  board, e.g. `uart:/dev/ttyO1@115200`; baud 1200 … 921600, default 115200). Vehicle ids are
  1..32 characters of `a-z A-Z 0-9 _ -`.

  Wiring (`sitl` and `uart` vehicles, see `Neptunus.Wiring`): the motors in `go()` order
  separated by `/`, `-` before a reversed one, optionally `:FORWARD:REVERSE` motor modifiers
  after a motor (percent, multiples of 100, default 100 and 100; sent as `mtrmod1`/`mtrmod2`),
  optionally `/direct` or `/ramp` (`go()`'s 4th argument 1 or 0; no effect on OpenROV 2.5.x
  and 30.x firmware, whose values apply at its next 50 ms tick either way); default
  `-port/vertical/starboard/direct` (the thesis' Neptunus). Example:
  `NEPTUNUS_WIRING=rov=port/vertical/-starboard:100:200`.

  Firmware (`sitl` and `uart` vehicles, see docs/OPENROV.md): `openrov-2.5` (OpenROV 2.5.x:
  plain `;`-terminated commands) or `openrov-30` (OpenROV 30.x: every command prefixed with
  its CRC-8 byte). Example: `NEPTUNUS_FIRMWARE=rov=openrov-30`. The board link reports a
  board whose output shows the other line; it never switches on its own.

  Model: the vehicle's parameter set in `priv/vehicles/` (`neptunus`, `thesis-4dof`, …, see
  `Neptunus.Dynamics.Params`): what its simulator flies (`simulated` and `sitl` boards, and
  run mode simulator on a real board) and the model of its navigation filter. Example:
  `NEPTUNUS_MODELS=a=thesis-4dof`.

  Camera (see `Neptunus.Camera.Source`): `v4l2:DEVICE[@WxH][@FPS]` (a webcam through ffmpeg,
  its own MJPEG), `testsrc[@WxH][@FPS]` (ffmpeg's test pattern) or `exec:PROGRAM [ARGS]` (any
  program writing MJPEG to its output). Example: `NEPTUNUS_CAMERAS=rov=v4l2:/dev/video0@1280x720@30`.

  Security (`auth!/2`, `tls!/1`) and helm timing (`helm!/1`):

  | variable                       | meaning                                             | default        |
  |--------------------------------|-----------------------------------------------------|----------------|
  | `NEPTUNUS_SECRET`              | token signing secret, ≥ 32 characters               | none: local mode on loopback |
  | `NEPTUNUS_USERS_FILE`          | users file, lines `name role hash`                  | none           |
  | `NEPTUNUS_USERS`               | users inline, `name:role:hash,...`                  | none           |
  | `NEPTUNUS_ANONYMOUS_OBSERVERS` | connections without login may watch                 | `false`        |
  | `NEPTUNUS_ORIGINS`             | allowed browser origins, comma-separated            | same origin    |
  | `NEPTUNUS_TOKEN_TTL_S`         | login token lifetime (s)                            | 43200          |
  | `NEPTUNUS_LOGIN_ATTEMPTS`      | login attempts per minute per address               | 10             |
  | `NEPTUNUS_TLS_CERT`, `NEPTUNUS_TLS_KEY` | PEM certificate and key: serve HTTPS/WSS   | none (HTTP)    |
  | `NEPTUNUS_DEADMAN_MS`          | pilot silence that stops the vehicle (ms)           | 500            |
  | `NEPTUNUS_REQUEST_TIMEOUT_MS`  | how long a control request waits for the pilot (ms) | 10000          |
  | `NEPTUNUS_TAKEOVER_MS`         | main station takeover warning countdown (ms)        | 3000           |

  Roles: `pilot`, `observer`, `main_station` (at most one). A bind address other than
  loopback without a secret and users stops the node with a message saying what to set.
  """

  require Logger

  @type endpoint :: %{port: :inet.port_number(), bind: :inet.ip_address()}
  @typedoc "A vehicle; `sim: [vehicle: name]` when `NEPTUNUS_MODELS` names its parameter set."
  @type vehicle ::
          %{
            required(:id) => String.t(),
            required(:board) => :simulated,
            optional(:sim) => keyword()
          }
          | %{
              required(:id) => String.t(),
              required(:board) => :sitl,
              required(:wiring) => Neptunus.Wiring.t(),
              required(:firmware) => Neptunus.Protocol.OpenROV.profile(),
              optional(:sim) => keyword(),
              optional(:camera) => Neptunus.Camera.Source.t()
            }
          | %{
              required(:id) => String.t(),
              required(:board) => :uart,
              required(:device) => String.t(),
              required(:baud) => pos_integer(),
              required(:wiring) => Neptunus.Wiring.t(),
              required(:firmware) => Neptunus.Protocol.OpenROV.profile(),
              optional(:sim) => keyword(),
              optional(:camera) => Neptunus.Camera.Source.t()
            }

  @default_vehicles "neptunus-1=simulated"
  @boards %{"simulated" => :simulated, "sitl" => :sitl}
  @bauds [1200, 2400, 4800, 9600, 19_200, 38_400, 57_600, 115_200, 230_400, 460_800, 921_600]

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
  Vehicles from `NEPTUNUS_VEHICLES` (and their wiring from `NEPTUNUS_WIRING`).

      iex> Neptunus.Config.vehicles!(%{"NEPTUNUS_VEHICLES" => "a=simulated, b=simulated"})
      [%{id: "a", board: :simulated}, %{id: "b", board: :simulated}]

      iex> [rov] = Neptunus.Config.vehicles!(%{"NEPTUNUS_VEHICLES" => "rov=uart:/dev/ttyO1@57600"})
      iex> Map.take(rov, [:id, :board, :device, :baud])
      %{id: "rov", board: :uart, device: "/dev/ttyO1", baud: 57600}
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
      [] ->
        vehicles
        |> wiring!(Map.get(env, "NEPTUNUS_WIRING", ""))
        |> firmware!(Map.get(env, "NEPTUNUS_FIRMWARE", ""))
        |> models!(Map.get(env, "NEPTUNUS_MODELS", ""))
        |> cameras!(Map.get(env, "NEPTUNUS_CAMERAS", ""))

      [dup | _] ->
        bad!("NEPTUNUS_VEHICLES", spec, "unique vehicle ids (#{inspect(dup)} repeats)")
    end
  end

  # Every sitl/uart vehicle gets a wiring: the configured one or the default.
  defp wiring!(vehicles, spec) do
    configured =
      pairs!(
        "NEPTUNUS_WIRING",
        spec,
        vehicles,
        "id=wiring pairs, e.g. rov=-port/vertical/starboard"
      )
      |> Map.new(fn {%{id: id, board: board}, pair, text} ->
        cond do
          board not in [:sitl, :uart] ->
            bad!("NEPTUNUS_WIRING", spec, "sitl or uart vehicles (#{id} is #{board})")

          true ->
            case Neptunus.Wiring.parse(text) do
              {:ok, wiring} -> {id, wiring}
              {:error, reason} -> bad!("NEPTUNUS_WIRING", spec, "#{reason} in #{inspect(pair)}")
            end
        end
      end)

    defaults =
      for %{board: board, id: id} <- vehicles,
          board in [:sitl, :uart],
          into: %{},
          do: {id, Neptunus.Wiring.default()}

    put_configured(vehicles, Map.merge(defaults, configured), :wiring)
  end

  # Every sitl/uart vehicle gets a firmware profile: the configured one or openrov-2.5.
  defp firmware!(vehicles, spec) do
    configured =
      pairs!("NEPTUNUS_FIRMWARE", spec, vehicles, "id=firmware pairs, e.g. rov=openrov-30")
      |> Map.new(fn {%{id: id, board: board}, pair, text} ->
        cond do
          board not in [:sitl, :uart] ->
            bad!("NEPTUNUS_FIRMWARE", spec, "sitl or uart vehicles (#{id} is #{board})")

          true ->
            case Neptunus.Protocol.BoardLink.parse_profile(text) do
              {:ok, profile} -> {id, profile}
              {:error, reason} -> bad!("NEPTUNUS_FIRMWARE", spec, "#{reason} in #{inspect(pair)}")
            end
        end
      end)

    defaults =
      for %{board: board, id: id} <- vehicles,
          board in [:sitl, :uart],
          into: %{},
          do: {id, :openrov_25}

    put_configured(vehicles, Map.merge(defaults, configured), :firmware)
  end

  # A vehicle's parameter set, for the simulator (simulated and sitl boards, and run mode
  # simulator on a real board) and for the navigation filter's model.
  defp models!(vehicles, spec) do
    configured =
      pairs!("NEPTUNUS_MODELS", spec, vehicles, "id=model pairs, e.g. rov=thesis-4dof")
      |> Map.new(fn {%{id: id}, _pair, name} ->
        if name in Neptunus.Dynamics.Params.available() do
          {id, [vehicle: name]}
        else
          bad!(
            "NEPTUNUS_MODELS",
            spec,
            "a parameter set of priv/vehicles/ for #{id}: one of " <>
              Enum.join(Neptunus.Dynamics.Params.available(), ", ") <> " (got #{inspect(name)})"
          )
        end
      end)

    put_configured(vehicles, configured, :sim)
  end

  # A vehicle's camera source (Neptunus.Camera.Source).
  defp cameras!(vehicles, spec) do
    configured =
      pairs!("NEPTUNUS_CAMERAS", spec, vehicles, "id=source pairs, e.g. rov=v4l2:/dev/video0")
      |> Map.new(fn {%{id: id}, pair, text} ->
        case Neptunus.Camera.Source.parse(text) do
          {:ok, source} -> {id, source}
          {:error, reason} -> bad!("NEPTUNUS_CAMERAS", spec, "#{reason} in #{inspect(pair)}")
        end
      end)

    put_configured(vehicles, configured, :camera)
  end

  # each vehicle with a configured value (by id) gets it under `key`
  defp put_configured(vehicles, configured, key) do
    Enum.map(vehicles, fn %{id: id} = vehicle ->
      case Map.fetch(configured, id) do
        {:ok, value} -> Map.put(vehicle, key, value)
        :error -> vehicle
      end
    end)
  end

  # The `id=value` pairs of a per-vehicle variable as `{vehicle, pair, value}`; every id
  # must be a configured vehicle.
  defp pairs!(var, spec, vehicles, shape) do
    spec
    |> String.split(",", trim: true)
    |> Enum.map(&String.trim/1)
    |> Enum.reject(&(&1 == ""))
    |> Enum.map(fn pair ->
      case String.split(pair, "=", parts: 2) do
        [id, text] ->
          id = String.trim(id)

          case Enum.find(vehicles, &(&1.id == id)) do
            nil -> bad!(var, spec, "ids of configured vehicles (no vehicle #{inspect(id)})")
            vehicle -> {vehicle, pair, String.trim(text)}
          end

        _ ->
          bad!(var, spec, shape)
      end
    end)
  end

  defp vehicle!(pair, spec) do
    case String.split(pair, "=", parts: 2) do
      [id, board] ->
        id = String.trim(id)

        unless Regex.match?(~r/^[A-Za-z0-9_-]{1,32}$/, id) do
          bad!(
            "NEPTUNUS_VEHICLES",
            spec,
            "vehicle ids of 1..32 characters a-z A-Z 0-9 _ - (got #{inspect(id)})"
          )
        end

        case board(String.trim(board)) do
          {:ok, board} ->
            Map.put(board, :id, id)

          {:bad_uart, why} ->
            bad!("NEPTUNUS_VEHICLES", spec, "uart:DEVICE[@BAUD] in #{inspect(pair)}: #{why}")

          :error ->
            bad!(
              "NEPTUNUS_VEHICLES",
              spec,
              "a known board in #{inspect(pair)}: one of " <>
                "#{Enum.join(Map.keys(@boards), ", ")}, uart:DEVICE[@BAUD]"
            )
        end

      _ ->
        bad!("NEPTUNUS_VEHICLES", spec, "id=board pairs separated by commas, e.g. rov=simulated")
    end
  end

  defp board("uart:" <> device_baud) do
    {device, baud} =
      case String.split(device_baud, "@") do
        [device] -> {device, "115200"}
        [device, baud] -> {device, baud}
        _ -> {"", ""}
      end

    cond do
      not String.starts_with?(device, "/") ->
        {:bad_uart, "the device must be an absolute path such as /dev/ttyO1"}

      not match?({_, ""}, Integer.parse(baud)) or elem(Integer.parse(baud), 0) not in @bauds ->
        {:bad_uart, "the baud rate must be one of #{Enum.join(@bauds, ", ")}"}

      true ->
        {:ok, %{board: :uart, device: device, baud: String.to_integer(baud)}}
    end
  end

  defp board(name) do
    with {:ok, board} <- Map.fetch(@boards, name), do: {:ok, %{board: board}}
  end

  @doc """
  Login and connection security (`config :neptunus, :auth`, see `NeptunusWeb.Auth`) from the
  environment, for the `endpoint` it protects.

  Secure by default: bound to a loopback address with neither `NEPTUNUS_SECRET` nor users,
  the node runs in *local mode* (no logins; anyone on this computer may pilot). Any other
  bind address needs a secret and users, and so does a configuration that has one of them.

      iex> Neptunus.Config.auth!(%{}, %{bind: {127, 0, 0, 1}}).mode
      :local
  """
  @spec auth!(%{optional(String.t()) => String.t()}, %{bind: :inet.ip_address()}) :: map()
  def auth!(env, %{bind: bind}) do
    secret = secret!(Map.get(env, "NEPTUNUS_SECRET"))
    users = users!(env)

    settings = %{
      secret: secret,
      users: users,
      anonymous_observers: env_boolean!(env, "NEPTUNUS_ANONYMOUS_OBSERVERS", false),
      origins: origins!(Map.get(env, "NEPTUNUS_ORIGINS", "")),
      token_ttl_s: env_integer!(env, "NEPTUNUS_TOKEN_TTL_S", 43_200, 60..2_592_000),
      login_attempts_per_minute: env_integer!(env, "NEPTUNUS_LOGIN_ATTEMPTS", 10, 1..1000)
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
  TLS from `NEPTUNUS_TLS_CERT` and `NEPTUNUS_TLS_KEY` (PEM files, both or neither): nil or
  `%{certfile, keyfile}`.

      iex> Neptunus.Config.tls!(%{})
      nil
  """
  @spec tls!(%{optional(String.t()) => String.t()}) ::
          %{certfile: String.t(), keyfile: String.t()} | nil
  def tls!(env) do
    case {Map.get(env, "NEPTUNUS_TLS_CERT", ""), Map.get(env, "NEPTUNUS_TLS_KEY", "")} do
      {"", ""} ->
        nil

      {cert, ""} ->
        bad!(
          "NEPTUNUS_TLS_KEY",
          "",
          "the private key (PEM) that goes with NEPTUNUS_TLS_CERT=#{cert}"
        )

      {"", key} ->
        bad!(
          "NEPTUNUS_TLS_CERT",
          "",
          "the certificate (PEM) that goes with NEPTUNUS_TLS_KEY=#{key}"
        )

      {cert, key} ->
        for {variable, path} <- [{"NEPTUNUS_TLS_CERT", cert}, {"NEPTUNUS_TLS_KEY", key}],
            not File.regular?(path),
            do: bad!(variable, path, "a readable PEM file (no such file)")

        %{certfile: Path.expand(cert), keyfile: Path.expand(key)}
    end
  end

  @doc """
  Helm timing (`config :neptunus, :helm`, see `Neptunus.Vehicle.Helm`).

      iex> Neptunus.Config.helm!(%{})
      [deadman_ms: 500, request_timeout_ms: 10000, takeover_ms: 3000]
  """
  @spec helm!(%{optional(String.t()) => String.t()}) :: keyword(pos_integer())
  def helm!(env) do
    [
      deadman_ms: env_integer!(env, "NEPTUNUS_DEADMAN_MS", 500, 100..10_000),
      request_timeout_ms: env_integer!(env, "NEPTUNUS_REQUEST_TIMEOUT_MS", 10_000, 1000..120_000),
      takeover_ms: env_integer!(env, "NEPTUNUS_TAKEOVER_MS", 3_000, 0..30_000)
    ]
  end

  @doc """
  Recording (`config :neptunus, :recording`, see `Neptunus.Vehicle.Recorder`):
  `NEPTUNUS_RECORDINGS` — the directory (relative to the working directory, created when
  needed) or `off`; `NEPTUNUS_RECORDING_MIN_FREE_MB` — recording stops while less disk is
  free (default 512); `NEPTUNUS_RECORDING_MAX_MB` — size of one file before the next is
  started (1..65536, default 256); `NEPTUNUS_RECORDING_KEEP_DAYS` — each vehicle's recorder
  deletes its recordings last written more than this many days ago (1..3650), or `forever`
  (the default: nothing is deleted by the server).

      iex> Neptunus.Config.recording!(%{}, "recordings")
      %{dir: "recordings", max_bytes: 268435456, min_free_bytes: 536870912, keep_ms: nil}
      iex> Neptunus.Config.recording!(%{"NEPTUNUS_RECORDING_KEEP_DAYS" => "30"}, "recordings").keep_ms
      2592000000
      iex> Neptunus.Config.recording!(%{"NEPTUNUS_RECORDINGS" => "off"}, "recordings").dir
      nil
  """
  @spec recording!(%{optional(String.t()) => String.t()}, Path.t() | nil) :: %{
          dir: Path.t() | nil,
          max_bytes: pos_integer(),
          min_free_bytes: non_neg_integer(),
          keep_ms: pos_integer() | nil
        }
  def recording!(env, default_dir) do
    dir =
      case env |> Map.get("NEPTUNUS_RECORDINGS", default_dir || "off") |> String.trim() do
        "off" -> nil
        "" -> bad!("NEPTUNUS_RECORDINGS", "", "a directory, or off")
        dir -> recording_dir!(dir)
      end

    %{
      dir: dir,
      max_bytes: env_integer!(env, "NEPTUNUS_RECORDING_MAX_MB", 256, 1..65_536) * 1024 * 1024,
      min_free_bytes:
        env_integer!(env, "NEPTUNUS_RECORDING_MIN_FREE_MB", 512, 0..1_048_576) * 1024 * 1024,
      keep_ms: keep_ms!(env)
    }
  end

  @doc """
  The scheduler time slice the node's threads ask the OS for (`Neptunus.OS`), in
  nanoseconds: `NEPTUNUS_OS_SLICE_US` in µs, 100..100000 (default 100), or `default` (nil:
  leave the kernel's own).

      iex> Neptunus.Config.os_time_slice_ns!(%{})
      100000
      iex> Neptunus.Config.os_time_slice_ns!(%{"NEPTUNUS_OS_SLICE_US" => "500"})
      500000
      iex> Neptunus.Config.os_time_slice_ns!(%{"NEPTUNUS_OS_SLICE_US" => "default"})
      nil
  """
  @spec os_time_slice_ns!(%{optional(String.t()) => String.t()}) :: pos_integer() | nil
  def os_time_slice_ns!(env) do
    case integer_or_word!(
           env,
           "NEPTUNUS_OS_SLICE_US",
           "100",
           100..100_000,
           "default",
           "microseconds"
         ) do
      nil -> nil
      us -> us * 1000
    end
  end

  @doc """
  The most client connections (HTTP and WebSocket) served at once: `NEPTUNUS_MAX_CONNECTIONS`,
  1..1048576, or nil when unset (`NeptunusWeb.Endpoint` derives it from the descriptor limit,
  and lowers a configured value the limit cannot hold).

      iex> Neptunus.Config.max_connections!(%{})
      nil
      iex> Neptunus.Config.max_connections!(%{"NEPTUNUS_MAX_CONNECTIONS" => "500"})
      500
  """
  @spec max_connections!(%{optional(String.t()) => String.t()}) :: pos_integer() | nil
  def max_connections!(env),
    do: env_integer!(env, "NEPTUNUS_MAX_CONNECTIONS", nil, 1..1_048_576)

  defp keep_ms!(env) do
    case integer_or_word!(
           env,
           "NEPTUNUS_RECORDING_KEEP_DAYS",
           "forever",
           1..3650,
           "forever",
           "a number of days"
         ) do
      nil -> nil
      days -> days * 86_400_000
    end
  end

  # `variable` (default `default`): an integer in `range`, or `word` (nil); else a clear error
  # saying "<what> in <range>, or <word>"
  defp integer_or_word!(env, variable, default, first..last, word, what) do
    value = Map.get(env, variable, default)
    trimmed = String.trim(value)

    case Integer.parse(trimmed) do
      _ when trimmed == word -> nil
      {n, ""} when n >= first and n <= last -> n
      _ -> bad!(variable, value, "#{what} in #{first}..#{last}, or #{word}")
    end
  end

  defp recording_dir!(dir) do
    case File.stat(dir) do
      {:ok, %File.Stat{type: :directory}} ->
        dir

      {:ok, _} ->
        bad!("NEPTUNUS_RECORDINGS", dir, "a directory (this is a file), or off")

      {:error, :enoent} ->
        dir

      {:error, reason} ->
        bad!("NEPTUNUS_RECORDINGS", dir, "a usable directory (#{reason}), or off")
    end
  end

  defp loopback?({127, _, _, _}), do: true
  defp loopback?({0, 0, 0, 0, 0, 0, 0, 1}), do: true
  defp loopback?(_), do: false

  defp secret!(nil), do: nil
  defp secret!(""), do: nil

  defp secret!(secret) do
    if byte_size(secret) >= 32,
      do: secret,
      else:
        bad!(
          "NEPTUNUS_SECRET",
          "(#{byte_size(secret)} characters)",
          "at least 32 characters, e.g. the output of `openssl rand -base64 48`"
        )
  end

  defp users!(env) do
    from_file =
      case Map.get(env, "NEPTUNUS_USERS_FILE", "") do
        "" ->
          []

        path ->
          case File.read(path) do
            {:ok, text} ->
              warn_users_file(path)

              text
              |> String.split("\n")
              |> Enum.with_index(1)
              |> Enum.map(fn {line, n} ->
                {line |> String.split("#") |> hd() |> String.trim(), n}
              end)
              |> Enum.reject(fn {line, _} -> line == "" end)
              |> Enum.map(fn {line, n} ->
                user!(String.split(line), "NEPTUNUS_USERS_FILE", "#{path}, line #{n}")
              end)

            {:error, reason} ->
              bad!("NEPTUNUS_USERS_FILE", path, "a readable file (#{:file.format_error(reason)})")
          end
      end

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
      [] -> :ok
      [dup | _] -> bad!("NEPTUNUS_USERS", dup, "unique user names (#{dup} is defined twice)")
    end

    case Enum.filter(users, &(&1.role == :main_station)) do
      [_, _ | _] = mains ->
        bad!("NEPTUNUS_USERS", Enum.map_join(mains, ",", & &1.name), "at most one main_station")

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

      iex> Neptunus.Config.users_file_warning("/etc/neptunus/users", 0o100600)
      nil
      iex> Neptunus.Config.users_file_warning("/etc/neptunus/users", 0o100644)
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
        bad!(variable, where, "user names of 1..40 characters a-z A-Z 0-9 _ . @ -")

      not Map.has_key?(@roles, role) ->
        bad!(variable, where, "a role: pilot, observer or main_station (got #{inspect(role)})")

      match?({:error, _}, NeptunusWeb.Auth.Password.parse(hash)) ->
        bad!(variable, where, "a password hash from `mix neptunus.passwd NAME ROLE`")

      true ->
        %{name: name, role: Map.fetch!(@roles, role), hash: hash}
    end
  end

  defp user!(_fields, "NEPTUNUS_USERS", where),
    do: bad!("NEPTUNUS_USERS", where, "name:role:hash entries separated by commas")

  defp user!(_fields, variable, where),
    do: bad!(variable, where, "lines `name role hash`")

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
          bad!(
            "NEPTUNUS_ORIGINS",
            spec,
            "origins like https://rov.example.org or http://10.0.0.2:4000"
          )
      end
    end)
  end

  defp env_boolean!(env, variable, default) do
    case env |> Map.get(variable, "") |> String.trim() |> String.downcase() do
      "" -> default
      v when v in ["true", "1", "yes"] -> true
      v when v in ["false", "0", "no"] -> false
      v -> bad!(variable, v, "true or false")
    end
  end

  defp env_integer!(env, variable, default, range) do
    case Map.get(env, variable) do
      nil ->
        default

      value ->
        case Integer.parse(String.trim(value)) do
          {n, ""} ->
            if n in range, do: n, else: bad!(variable, value, "an integer in #{inspect(range)}")

          _ ->
            bad!(variable, value, "an integer in #{inspect(range)}")
        end
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
