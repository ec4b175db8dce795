defmodule Neptunus.Settings do
  @moduledoc """
  The node's settings store: small JSON values kept per user and per vehicle, on disk, so they
  follow a pilot from device to device (the gamepad mapping, the developer page's plots) and
  a vehicle's settings are the same on every device (camera rotation, tuning).

      Neptunus.Settings.put({:user, "alice"}, "gamepad.mapping", %{"0" => "stop"})
      Neptunus.Settings.get({:user, "alice"}, "gamepad.mapping")  #=> {:ok, %{"0" => "stop"}}
      Neptunus.Settings.delete({:user, "alice"}, "gamepad.mapping")

  Scopes, keys, values and their limits are `Neptunus.Settings.Rules`' (pure); this process
  only reads and writes the files, one per scope, and keeps the scopes it has read in memory.

  ## Who is a user

  In secure mode a user is the authenticated user name (`NEPTUNUS_USERS`): what alice stores
  from her tablet she finds on the main station's laptop. Anonymous observers have no
  settings (their name is made up per connection). In local mode there are no logins and
  every connection's name is only a label, so the whole node has one user, `"local"`
  (`local_user/0`; `NeptunusWeb.API.Request.user_scope/1` maps a request to its scope).

  ## Durability

  A write goes to a temporary file beside the scope's file, is `fsync`ed, and renamed over
  the file (atomic on POSIX): a crash or a full disk leaves either the old file or the new
  one, never half of one (the rename itself reaches the disk with the file system's next
  journal commit: a power cut just after `put/3` returned may bring back the previous
  value, never a broken file). When a write fails the store keeps the previous value, in memory
  and on disk, and `put/3` or `delete/2` says why. A file that cannot be read (not JSON, or
  not the settings of its scope) does not stop the node: it is reported (server log, error
  level, naming the file and the reason), moved aside as `<file>.corrupt-<UTC time>` for a
  person to look at, and the scope starts empty. A file that cannot be read at all (permissions, I/O)
  is left alone: its scope's requests fail, saying so, until it can be read.

  The directory is `NEPTUNUS_SETTINGS` (`Neptunus.Config.Settings`), read once at boot and
  handed to this process as its `:dir` option; it is created when first written.
  """
  use GenServer

  require Logger

  alias Neptunus.Settings.Rules

  @type scope :: Rules.scope()

  @doc "The one user of a node in local mode (no logins): `\"local\"`."
  @spec local_user() :: String.t()
  def local_user, do: "local"

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            dir: Path.t(),
            sync: (term() -> :ok | {:error, term()}),
            scopes: %{
              optional(Neptunus.Settings.Rules.scope()) => Neptunus.Settings.Rules.settings()
            }
          }
    @enforce_keys [:dir]
    defstruct dir: nil, sync: &:file.sync/1, scopes: %{}
  end

  @doc """
  Starts the store. Options: `:dir` (required: the settings directory), `:name` (default
  `Neptunus.Settings`) and, for tests, `:sync` (flushes an open file to the disk, like
  `:file.sync/1`).
  """
  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts) do
    {name, opts} = Keyword.pop(opts, :name, __MODULE__)
    GenServer.start_link(__MODULE__, opts, name: name)
  end

  @doc "The value of `key` in `scope`, or `:error` when none is stored (or the scope or key is bad)."
  @spec get(scope(), String.t()) :: {:ok, term()} | :error
  @spec get(GenServer.server(), scope(), String.t()) :: {:ok, term()} | :error
  def get(server \\ __MODULE__, scope, key), do: GenServer.call(server, {:get, scope, key})

  @doc "Every setting of `scope` (an empty map when none, or when the scope is bad)."
  @spec all(GenServer.server(), scope()) :: Rules.settings()
  def all(server \\ __MODULE__, scope), do: GenServer.call(server, {:all, scope})

  @doc """
  Stores `value` under `key` in `scope`, on disk before it returns. `{:error, reason}` for a
  bad scope, key or value (`Neptunus.Settings.Rules`) or a failed write; nothing changes then.
  """
  @spec put(scope(), String.t(), term()) :: :ok | {:error, String.t()}
  @spec put(GenServer.server(), scope(), String.t(), term()) :: :ok | {:error, String.t()}
  def put(server \\ __MODULE__, scope, key, value),
    do: GenServer.call(server, {:put, scope, key, value})

  @doc "Removes `key` from `scope` (`:ok` when it was not there); like `put/3` on errors."
  @spec delete(scope(), String.t()) :: :ok | {:error, String.t()}
  @spec delete(GenServer.server(), scope(), String.t()) :: :ok | {:error, String.t()}
  def delete(server \\ __MODULE__, scope, key), do: GenServer.call(server, {:delete, scope, key})

  @impl true
  def init(opts) do
    case Keyword.fetch(opts, :dir) do
      {:ok, dir} when is_binary(dir) and dir != "" ->
        {:ok, %State{dir: dir, sync: Keyword.get(opts, :sync, &:file.sync/1)}}

      _ ->
        {:stop, "Neptunus.Settings needs a :dir (the settings directory)"}
    end
  end

  @impl true
  def handle_call({:get, scope, key}, _from, state) do
    with :ok <- Rules.scope(scope),
         :ok <- Rules.key(key),
         {:ok, settings, state} <- load(state, scope) do
      {:reply, Map.fetch(settings, key), state}
    else
      {:error, _} -> {:reply, :error, state}
    end
  end

  def handle_call({:all, scope}, _from, state) do
    with :ok <- Rules.scope(scope),
         {:ok, settings, state} <- load(state, scope) do
      {:reply, settings, state}
    else
      {:error, _} -> {:reply, %{}, state}
    end
  end

  def handle_call({:put, scope, key, value}, _from, state) do
    with :ok <- Rules.scope(scope),
         {:ok, settings, state} <- load(state, scope),
         {:ok, new} <- Rules.put(settings, key, value) do
      store(state, scope, new)
    else
      {:error, reason} -> {:reply, {:error, reason}, state}
    end
  end

  def handle_call({:delete, scope, key}, _from, state) do
    with :ok <- Rules.scope(scope),
         :ok <- Rules.key(key),
         {:ok, settings, state} <- load(state, scope) do
      if Map.has_key?(settings, key),
        do: store(state, scope, Map.delete(settings, key)),
        else: {:reply, :ok, state}
    else
      {:error, reason} -> {:reply, {:error, reason}, state}
    end
  end

  defp store(state, scope, settings) do
    path = Rules.path(state.dir, scope)

    case write_atomically(path, Rules.encode_file(scope, settings), state.sync) do
      :ok ->
        {:reply, :ok, put_in(state.scopes[scope], settings)}

      {:error, reason} ->
        Logger.error("settings: cannot write #{path}: #{reason}")
        {:reply, {:error, "cannot store the setting: #{reason}"}, state}
    end
  end

  # The scope's settings, read from its file the first time. A file that cannot be read now
  # (permissions, I/O) is not taken for an empty one: writing the scope would replace what
  # it holds. The scope is refused (and read again next time) until it can be read.
  defp load(state, scope) do
    case Map.fetch(state.scopes, scope) do
      {:ok, settings} ->
        {:ok, settings, state}

      :error ->
        path = Rules.path(state.dir, scope)

        case read(path, scope) do
          {:ok, settings} ->
            {:ok, settings, put_in(state.scopes[scope], settings)}

          {:error, reason} ->
            Logger.error("settings: cannot read #{path}: #{reason}")
            {:error, "cannot read the settings: #{reason}"}
        end
    end
  end

  defp read(path, scope) do
    case File.read(path) do
      {:ok, text} ->
        case Rules.decode_file(text, scope) do
          {:ok, settings} -> {:ok, settings}
          {:error, reason} -> {:ok, set_aside(path, reason)}
        end

      # no file (or a file where a directory of the path should be: no file either)
      {:error, posix} when posix in [:enoent, :enotdir] ->
        {:ok, %{}}

      {:error, posix} ->
        {:error, to_string(:file.format_error(posix))}
    end
  end

  defp set_aside(path, reason) do
    stamp = Calendar.strftime(DateTime.utc_now(), "%Y%m%dT%H%M%SZ")
    aside = "#{path}.corrupt-#{stamp}"

    moved =
      case File.rename(path, aside) do
        :ok -> "moved aside as #{aside}"
        {:error, posix} -> "could not move it aside (#{:file.format_error(posix)})"
      end

    Logger.error(
      "settings: #{path} is corrupt (#{Neptunus.Log.safe(reason)}): its settings are not used; " <>
        "#{moved}"
    )

    %{}
  end

  # temp file + fsync + rename: the file is either the old one or the new one
  defp write_atomically(path, text, sync) do
    tmp = "#{path}.tmp-#{System.unique_integer([:positive])}"

    result =
      with :ok <- File.mkdir_p(Path.dirname(path)),
           {:ok, io} <- :file.open(tmp, [:write, :raw, :binary]),
           :ok <- write_sync_close(io, text, sync) do
        :file.rename(tmp, path)
      end

    case result do
      :ok ->
        :ok

      {:error, posix} ->
        _ = File.rm(tmp)
        {:error, :file.format_error(posix) |> to_string()}
    end
  end

  defp write_sync_close(io, text, sync) do
    with :ok <- :file.write(io, text),
         :ok <- sync.(io) do
      :file.close(io)
    else
      error ->
        _ = :file.close(io)
        error
    end
  end
end
