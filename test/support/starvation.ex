defmodule Neptunus.Test.Starvation do
  @moduledoc """
  How long the test's own node was kept from a core: the run-queue wait (time ready to run,
  not running) the kernel counts for each thread in `/proc/<pid>/task/<tid>/schedstat`.

  A test that states a latency the system promises (the chaos test: a board at neutral within
  100 ms of a kill) measures wall-clock time, and on a machine whose cores are busy with other
  work the same code path takes as long as the kernel keeps it from running. The threads such
  a path runs on are the VM's schedulers and its I/O poller, and the port programs the VM runs
  (`erl_child_setup` and its children: the serial link's and a SITL board's programs).
  `waited/4` gives what they were kept waiting over an interval: the VM's threads together,
  plus, for a path through the port programs, the programs'. So a bound of
  `promise + waited` is the promise itself on a quiet machine and grows with the load on a
  busy one. It is generous (not every thread's wait delays a given path) and never short:
  the test must hold on a busy machine, and still catches a reaction that waits for a timer
  rather than an event (on a quiet machine a 300 ms delay put in on purpose; under heavy
  load one as long as the helm's deadman).

  The probe (`start_link/0`, linked to the caller) reads the counters every #{10} ms, with the
  monotonic time of each reading. An interval is measured between the readings around
  it: when the probe itself was kept waiting, those are further apart and the figure larger.

  Without the counters (no `/proc`, or schedstat not built into the kernel) `available?/1`
  is false and `waited/4` nil: the caller then reports its figure and does not bound it.
  """

  @period_ms 10

  @enforce_keys [:table, :available]
  defstruct [:table, :available]

  @type t :: %__MODULE__{table: :ets.tid(), available: boolean()}

  @doc "Starts the probe, linked to the caller (none when the counters are not available)."
  @spec start_link() :: t()
  def start_link do
    vm = List.to_string(:os.getpid())
    threads = scheduler_threads(vm)
    available = threads != [] and Enum.all?(threads, &(wait_ns(&1) != nil))
    me = self()

    # the probe owns its table: it goes with the probe, never from under it
    spawn_link(fn ->
      table = :ets.new(:starvation, [:ordered_set, :public, read_concurrency: true])
      send(me, {__MODULE__, :ready, table})

      if available do
        Process.flag(:priority, :high)
        probe(table, vm, threads)
      else
        Process.sleep(:infinity)
      end
    end)

    receive do
      {__MODULE__, :ready, table} -> %__MODULE__{table: table, available: available}
    end
  end

  @doc "Whether the kernel's counters could be read."
  @spec available?(t()) :: boolean()
  def available?(%__MODULE__{available: available}), do: available

  @doc """
  The run-queue wait (ms) between the readings around `from_ms` and `to_ms` (monotonic ms,
  or OS ms with `clock: :os`): the VM's threads', plus, with `programs: true` (a path
  through the port programs), the programs'. nil when the counters are not available. Waits
  for a reading at or after `to_ms` when there is none yet.
  """
  @spec waited(t(), integer(), integer(), keyword()) :: non_neg_integer() | nil
  def waited(probe, from_ms, to_ms, opts \\ [])

  def waited(%__MODULE__{available: false}, _from_ms, _to_ms, _opts), do: nil

  def waited(%__MODULE__{table: table}, from_ms, to_ms, opts) do
    # OS times to monotonic ones (the VM's offset between them, now)
    offset =
      if Keyword.get(opts, :clock, :monotonic) == :os,
        do: System.os_time(:millisecond) - System.monotonic_time(:millisecond),
        else: 0

    {from_ms, to_ms} = {from_ms - offset, to_ms - offset}
    await_reading(table, to_ms, Neptunus.Test.Patience.ms())
    before = reading(table, :ets.prev(table, from_ms + 1), &:ets.first/1)
    later = reading(table, :ets.next(table, to_ms - 1), &:ets.last/1)

    {vm, programs} =
      later
      |> Enum.map(fn {key, ns} -> {key, max(ns - Map.get(before, key, 0), 0)} end)
      |> Enum.split_with(fn {key, _ns} -> String.contains?(key, "/task/") end)

    vm = vm |> Enum.map(&elem(&1, 1)) |> Enum.sum()

    programs =
      if Keyword.get(opts, :programs, false),
        do: programs |> Enum.map(&elem(&1, 1)) |> Enum.sum(),
        else: 0

    div(vm + programs, 1_000_000)
  end

  # the counters of the reading at `key`, or at the table's end `otherwise` gives
  defp reading(table, :"$end_of_table", otherwise), do: reading(table, otherwise.(table), nil)
  defp reading(table, key, _otherwise), do: table |> :ets.lookup(key) |> hd() |> elem(1)

  defp await_reading(table, to_ms, left) do
    last = :ets.last(table)

    if (last != :"$end_of_table" and last >= to_ms) or left <= 0 do
      :ok
    else
      Process.sleep(@period_ms)
      await_reading(table, to_ms, left - @period_ms)
    end
  end

  # -- the probe --------------------------------------------------------------------------

  # Each reading: its monotonic time (ms) and each counter's value (ns).
  defp probe(table, vm, threads) do
    :ets.insert(table, {System.monotonic_time(:millisecond), read_all(vm, threads)})

    Process.sleep(@period_ms)
    probe(table, vm, threads)
  end

  defp read_all(vm, threads) do
    paths = threads ++ Enum.map(descendants(vm), &"/proc/#{&1}/schedstat")

    Enum.reduce(paths, %{}, fn path, acc ->
      case wait_ns(path) do
        nil -> acc
        ns -> Map.put(acc, path, ns)
      end
    end)
  end

  # The VM's schedulers and I/O poller: the threads whose names say so.
  defp scheduler_threads(vm) do
    case File.ls("/proc/#{vm}/task") do
      {:ok, tids} ->
        for tid <- tids,
            {:ok, name} <- [File.read("/proc/#{vm}/task/#{tid}/comm")],
            String.trim(name) =~ ~r/^\d+_(scheduler|poller)$/,
            do: "/proc/#{vm}/task/#{tid}/schedstat"

      {:error, _} ->
        []
    end
  end

  # erl_child_setup (the VM's child) and the programs it started (its children)
  defp descendants(vm) do
    children = children(vm)
    children ++ Enum.flat_map(children, &children/1)
  end

  defp children(pid) do
    case File.read("/proc/#{pid}/task/#{pid}/children") do
      {:ok, text} -> String.split(text)
      {:error, _} -> []
    end
  end

  # the second field of schedstat: time spent waiting on a run queue (ns)
  defp wait_ns(path) do
    with {:ok, text} <- File.read(path),
         [_run, wait | _] <- String.split(text),
         {ns, ""} <- Integer.parse(wait) do
      ns
    else
      _ -> nil
    end
  end
end
