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
  The environment for a port program of ours: `NEPTUNUS_SLICE_NS` when the node asks for a
  slice, so the program asks for it too (a port program is started by the VM's helper
  process, not by a thread that has the slice).
  """
  @spec port_env() :: [{charlist(), charlist()}]
  def port_env do
    case Application.get_env(:neptunus, :os_time_slice_ns) do
      ns when is_integer(ns) and ns > 0 -> [{~c"NEPTUNUS_SLICE_NS", Integer.to_charlist(ns)}]
      _ -> []
    end
  end

  @doc """
  At the node's start: requests `:os_time_slice_ns` (nil: nothing to do) and logs what came
  of it. Never fails the start.
  """
  @spec apply_configured() :: :ok
  def apply_configured do
    case Application.get_env(:neptunus, :os_time_slice_ns) do
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
end
