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
  | `NEPTUNUS_DIVE_GAP_MIN` | helm free this long (min) ends a dive; 0: never | 10 |
  | `NEPTUNUS_SETTINGS` | per-user and per-vehicle settings directory | `settings`           |
  | `NEPTUNUS_OS_SLICE_US` | OS time slice the server's threads ask for (µs, 100..100000), or `default` | 100 |
  | `NEPTUNUS_MAX_CONNECTIONS` | concurrent client connections (1..1048576); more are closed at once | from the descriptor limit |

  The variables are parsed by one module per domain: `Neptunus.Config.Endpoint`,
  `Neptunus.Config.Vehicles` (boards, wiring, firmware, models, cameras),
  `Neptunus.Config.Auth`, `Neptunus.Config.TLS`, `Neptunus.Config.Helm`,
  `Neptunus.Config.Recording`, `Neptunus.Config.Settings` and `Neptunus.Config.OS`; security and helm variables are
  listed in `Neptunus.Config.Auth` and `Neptunus.Config.Helm`. This module holds the
  parsing helpers they share.
  """

  @typedoc "The environment, as `System.get_env/0` returns it."
  @type env :: %{optional(String.t()) => String.t()}

  @doc "Raises the `ArgumentError` naming `variable`, its `value` and what was `expected`."
  @spec bad!(String.t(), term(), String.t()) :: no_return()
  def bad!(variable, value, expected) do
    raise ArgumentError, "#{variable}=#{inspect(value)} is not valid: expected #{expected}"
  end

  @doc """
  The entries of the file `variable` names (a users or keys file): for each line that is not
  blank or a comment (`#` to the end of a line), its words and where it is
  (`"PATH, line N"`, for errors). `[]` when `variable` is unset; a file that cannot be read
  raises the `ArgumentError` naming `variable`.
  """
  @spec file_entries!(env(), String.t()) :: [{[String.t()], String.t()}]
  def file_entries!(env, variable) do
    case Map.get(env, variable, "") do
      "" ->
        []

      path ->
        case File.read(path) do
          {:ok, text} ->
            text
            |> String.split("\n")
            |> Enum.with_index(1)
            |> Enum.map(fn {line, n} ->
              {line |> String.split("#") |> hd() |> String.trim(), n}
            end)
            |> Enum.reject(fn {line, _} -> line == "" end)
            |> Enum.map(fn {line, n} -> {String.split(line), "#{path}, line #{n}"} end)

          {:error, reason} ->
            bad!(variable, path, "a readable file (#{:file.format_error(reason)})")
        end
    end
  end

  @doc "`variable`: an integer in `range`, or `default` when unset."
  @spec env_integer!(env(), String.t(), default, Range.t()) :: integer() | default
        when default: term()
  def env_integer!(env, variable, default, range) do
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

  @doc "`variable`: `true`/`1`/`yes` or `false`/`0`/`no` (any case), or `default` when unset or empty."
  @spec env_boolean!(env(), String.t(), boolean()) :: boolean()
  def env_boolean!(env, variable, default) do
    case env |> Map.get(variable, "") |> String.trim() |> String.downcase() do
      "" -> default
      v when v in ["true", "1", "yes"] -> true
      v when v in ["false", "0", "no"] -> false
      v -> bad!(variable, v, "true or false")
    end
  end

  @doc """
  `variable` (the text `default` when unset): an integer in `range`, or `word` (nil); else
  a clear error saying "<what> in <range>, or <word>".
  """
  @spec integer_or_word!(env(), String.t(), String.t(), Range.t(), String.t(), String.t()) ::
          integer() | nil
  def integer_or_word!(env, variable, default, first..last, word, what) do
    value = Map.get(env, variable, default)
    trimmed = String.trim(value)

    case Integer.parse(trimmed) do
      _ when trimmed == word -> nil
      {n, ""} when n >= first and n <= last -> n
      _ -> bad!(variable, value, "#{what} in #{first}..#{last}, or #{word}")
    end
  end

  @doc """
  `HOST:PORT`, split at the last colon (an IPv6 address in brackets), the port in
  1..65535; `{:error, why}` otherwise. Pure.

      iex> Neptunus.Config.host_port("localhost:5760")
      {:ok, "localhost", 5760}
      iex> Neptunus.Config.host_port("[::1]:14550")
      {:ok, "::1", 14550}
      iex> Neptunus.Config.host_port("h:0")
      {:error, "the port must be in 1..65535"}
  """
  @spec host_port(String.t()) :: {:ok, String.t(), 1..65_535} | {:error, String.t()}
  def host_port(text) when is_binary(text) do
    case Regex.run(~r/^\[?([^\[\]\s]+?)\]?:([0-9]+)$/, text) do
      [_, host, port] ->
        case Integer.parse(port) do
          {port, ""} when port in 1..65_535 -> {:ok, host, port}
          _ -> {:error, "the port must be in 1..65535"}
        end

      nil ->
        {:error, "expected HOST:PORT (got #{inspect(text)})"}
    end
  end

  @doc """
  Words as alternatives in an error message.

      iex> Neptunus.Config.alternatives(["sitl", "uart"])
      "sitl or uart"
      iex> Neptunus.Config.alternatives(["a", "b", "c"])
      "a, b or c"
  """
  @spec alternatives([String.t()]) :: String.t()
  def alternatives([one]), do: one

  def alternatives([_ | _] = words),
    do: Enum.join(Enum.drop(words, -1), ", ") <> " or " <> List.last(words)
end
