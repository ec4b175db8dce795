defmodule Neptunus.OS do
  @moduledoc """
  Asks the operating system to wake the server's threads promptly: a short scheduler time
  slice for every thread of the VM and of the board's port program
  (`c_src/neptunus_os_nif.c`, built by `mix compile` into `priv/neptunus_os_nif.so`).

  A pilot's command crosses several threads that sleep until it comes: the VM's poll thread
  and a scheduler, then the port program that writes the serial line. Each wakes on a core
  that something else may hold — a camera's ffmpeg, a browser, other observers' traffic. Since
  Linux 6.12 the scheduler (EEVDF) lets a thread ask for a shorter slice (100 µs to 100 ms;
  the default is about 0.7 ms × (1 + log₂ cores)), and a waking thread with a shorter slice
  preempts the running one instead of waiting for its turn. It changes no priority: each
  thread gets the same share of the CPU as before, in shorter turns. No privilege is needed.

  The node asks at start (`Neptunus.Application`) for `:os_time_slice_ns`
  (`NEPTUNUS_OS_SLICE_US`, default 100 µs, `default` to leave the kernel's) and passes it to
  its port programs (`port_env/0`), which ask for themselves. Older kernels accept the
  request and ignore it; `request_time_slice/1` reads the slices back and says
  `{:error, :unsupported}` then. Nothing depends on it: it only shortens waits.
  Measured in `bench/control_latency` (bench/README.md).

  It also raises the node's file descriptor limit (`raise_fd_limit/0`, at start from
  `Neptunus.Application`): the soft `RLIMIT_NOFILE` to the hard one. Every client connection,
  open file and port program holds a descriptor; a systemd service starts with a soft limit of
  1024. The VM sizes its poll set for sockets from the soft limit in force when it starts
  (`socket_limit/0`), so the release's start script raises the limit before the VM starts
  (`rel/env.sh.eex`); the raise here covers the node's files and the port programs it starts
  later, which inherit it. `NeptunusWeb.Endpoint` keeps its connections below `socket_limit/0`.
  """

  require Logger

  @on_load :load
  @library ~c"neptunus_os_nif"

  @min_ns 100_000
  @max_ns 100_000_000

  @typedoc "A requested slice: 0 (the kernel's default) or 100 µs..100 ms, in nanoseconds."
  @type slice_ns :: 0 | 100_000..100_000_000

  # Self-contained on purpose, like Neptunus.Dynamics.Native.load/0: an @on_load function
  # runs while the module loads (also inside the compiler), before other modules of ours may
  # be available, so it cannot call a shared helper.
  @doc false
  def load do
    case :erlang.load_nif(:filename.join(priv_dir(), @library), 0) do
      :ok ->
        :ok

      {:error, {reason, text}} ->
        :persistent_term.put({__MODULE__, :load_error}, {reason, List.to_string(text)})
        :ok
    end
  end

  defp priv_dir do
    case :code.priv_dir(:neptunus) do
      {:error, :bad_name} -> ~c"priv"
      dir -> dir
    end
  end

  @doc """
  Requests a time slice of `ns` nanoseconds for every thread of the VM under the fair
  scheduler (0: the kernel's default again). `{:ok, threads}` once the kernel reports the
  slice back on them; `{:error, :unsupported}` when it accepted the request but ignores it
  (Linux before 6.12), `{:error, :unavailable}` without the C library, or the error of the
  system call (e.g. `:eperm`).
  """
  @spec request_time_slice(slice_ns()) :: {:ok, pos_integer()} | {:error, atom()}
  def request_time_slice(ns) when ns == 0 or (is_integer(ns) and ns in @min_ns..@max_ns) do
    with :ok <- available(),
         {:ok, threads} <- set_time_slice(ns),
         {:ok, slices} <- time_slices(0) do
      if ns == 0 or Enum.all?(slices, fn {_tid, slice} -> slice == ns end),
        do: {:ok, threads},
        else: {:error, :unsupported}
    end
  end

  @doc """
  The slice the kernel reports for each thread of OS process `os_pid` (0: the VM), as
  `{thread_id, ns}`; 0 where it reports none (kernels before 6.12).
  """
  @spec thread_slices(non_neg_integer()) ::
          {:ok, [{pos_integer(), non_neg_integer()}]} | {:error, atom()}
  def thread_slices(os_pid) when is_integer(os_pid) and os_pid >= 0 do
    with :ok <- available(), do: time_slices(os_pid)
  end

  @doc """
  The environment for a port program of ours when the node asks for a slice of `ns`
  nanoseconds (the configured `:os_time_slice_ns`, given to the board processes as their
  option of that name; nil: none): `NEPTUNUS_SLICE_NS`, so the program asks for it too (a
  port program is started by the VM's helper process, not by a thread that has the slice).

      iex> Neptunus.OS.port_env(100_000)
      [{~c"NEPTUNUS_SLICE_NS", ~c"100000"}]
      iex> Neptunus.OS.port_env(nil)
      []
  """
  @spec port_env(pos_integer() | nil) :: [{charlist(), charlist()}]
  def port_env(ns) when is_integer(ns) and ns > 0,
    do: [{~c"NEPTUNUS_SLICE_NS", Integer.to_charlist(ns)}]

  def port_env(nil), do: []

  @doc """
  At the node's start: requests the configured slice of `ns` nanoseconds
  (`:os_time_slice_ns`; nil: nothing to do) and logs what came of it. Never fails the start.
  """
  @spec apply_configured(pos_integer() | nil) :: :ok
  def apply_configured(ns) do
    case ns do
      ns when is_integer(ns) and ns > 0 ->
        us = div(ns, 1000)

        case request_time_slice(ns) do
          {:ok, threads} ->
            Logger.info("OS time slice #{us} µs requested for the VM's #{threads} threads")

          {:error, :unsupported} ->
            Logger.info(
              "OS time slice #{us} µs not applied: this kernel ignores per-thread slices " <>
                "(Linux 6.12 and later honour them)"
            )

          {:error, reason} ->
            Logger.warning("OS time slice #{us} µs not applied: #{inspect(reason)}")
        end

      _ ->
        :ok
    end

    :ok
  end

  @typedoc "A descriptor limit: a count, or `:infinity` (RLIM_INFINITY)."
  @type fd_count :: non_neg_integer() | :infinity

  @doc "The node's `RLIMIT_NOFILE`: `{:ok, {soft, hard}}`."
  @spec fd_limit() :: {:ok, {fd_count(), fd_count()}} | {:error, atom()}
  def fd_limit, do: with(:ok <- available(), do: get_fd_limit())

  @doc """
  Raises the soft `RLIMIT_NOFILE` to the hard limit (to the kernel's `fs.nr_open` when the hard
  limit is unlimited): `{:ok, {before, after}}`. Needs no privilege.
  """
  @spec raise_fd_limit() :: {:ok, {fd_count(), fd_count()}} | {:error, atom()}
  def raise_fd_limit, do: with(:ok <- available(), do: set_fd_limit())

  @doc """
  How many descriptors the VM can poll: the highest socket descriptor it can use, fixed when it
  started (the soft limit then; raising the limit later does not change it). Open files do not
  count against it, they need no polling.
  """
  @spec socket_limit() :: pos_integer()
  def socket_limit do
    :erlang.system_info(:check_io)
    |> List.wrap()
    |> List.flatten()
    |> Enum.flat_map(fn
      {:max_fds, n} when is_integer(n) -> [n]
      _ -> []
    end)
    |> Enum.min(fn -> 1024 end)
  end

  @doc """
  At the node's start: raises the soft descriptor limit to the hard one and logs the limits in
  force. Never fails the start.
  """
  @spec apply_fd_limit() :: :ok
  def apply_fd_limit do
    sockets = socket_limit()

    case safely(&raise_fd_limit/0) do
      {:ok, {same, same}} ->
        Logger.info("file descriptors: limit #{same}, #{sockets} for sockets")

      {:ok, {before, now}} ->
        Logger.info(
          "file descriptors: limit raised from #{before} to #{now} (the hard limit), " <>
            "#{sockets} for sockets (the limit when the VM started)"
        )

      {:error, reason} ->
        Logger.warning(
          "file descriptors: limit not raised (#{inspect(reason)}), #{sockets} for sockets"
        )
    end

    :ok
  end

  # a library older than this module lacks the function: say so instead of failing the start
  defp safely(fun) do
    fun.()
  rescue
    e in ErlangError -> {:error, {:unavailable, e.original}}
  end

  @doc "Whether the C library is loaded."
  @spec available?() :: boolean()
  def available?, do: load_error() == nil

  defp available, do: if(available?(), do: :ok, else: {:error, :unavailable})

  defp load_error, do: :persistent_term.get({__MODULE__, :load_error}, nil)

  # Replaced by the C library's functions when it loads.
  @doc false
  def set_time_slice(_ns), do: :erlang.nif_error({:not_loaded, load_error()})
  @doc false
  def time_slices(_os_pid), do: :erlang.nif_error({:not_loaded, load_error()})
  @doc false
  def get_fd_limit, do: :erlang.nif_error({:not_loaded, load_error()})
  @doc false
  def set_fd_limit, do: :erlang.nif_error({:not_loaded, load_error()})
end
