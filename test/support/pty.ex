defmodule Neptunus.Test.Pty do
  @moduledoc """
  Serial-line rigs for tests, without hardware.

    * `socat_pair!/1` — a `socat` pseudo-terminal pair, both ends raw, as symlinks `a` and `b`
      in a fresh directory; killed and removed when the test ends. Bytes written on one end
      come out of the other.
    * `open!/1` — the test's own end of a line: our port program (`neptunus_uart tty`) on a
      device, owned by the calling process; `write/2`, `recv_until/3` read and write it.

  Open both ends before writing: whoever opens an end later may flush what was queued for it
  (the port program drops stale input on open, as `tty.setraw()` does).
  """
  import ExUnit.Assertions

  alias Neptunus.Test.Patience
  alias Neptunus.Vehicle.Board.OpenROV.UART

  @type pair :: %{dir: String.t(), a: String.t(), b: String.t(), port: port(), os_pid: integer()}

  @doc """
  A board-link test rig for a vehicle id starting with `prefix`: a socat pair, the test's own
  end (`board`, on `a`) open, and the calling test process registered as the vehicle's
  navigation and telemetry (so it hears what the link tells them) and subscribed to the
  vehicle's topic. Returns `%{id, pair, board}`; the link under test opens `pair.b`.
  """
  @spec board_rig!(String.t()) :: %{id: String.t(), pair: map(), board: port()}
  def board_rig!(prefix) do
    id = "#{prefix}-#{System.unique_integer([:positive])}"
    pair = socat_pair!()
    board = open!(pair.a)
    {:ok, _} = Registry.register(Neptunus.Fleet.Registry, {Neptunus.Vehicle.Navigation, id}, nil)
    {:ok, _} = Registry.register(Neptunus.Fleet.Registry, {Neptunus.Vehicle.Telemetry, id}, nil)
    Neptunus.PubSub.subscribe(Neptunus.Vehicle.Telemetry.topic(id))
    %{id: id, pair: pair, board: board}
  end

  @doc "Starts socat with ends `a` and `b` (or the given link names) in a new temporary directory."
  @spec socat_pair!(keyword()) :: pair()
  def socat_pair!(opts \\ []) do
    dir =
      Keyword.get_lazy(opts, :dir, fn ->
        Path.join(System.tmp_dir!(), "neptunus-test-#{System.unique_integer([:positive])}")
      end)

    File.mkdir_p!(dir)
    a = Path.join(dir, Keyword.get(opts, :a, "a"))
    b = Path.join(dir, Keyword.get(opts, :b, "b"))
    socat = System.find_executable("socat") || flunk("socat is not installed (make setup)")

    port =
      Port.open({:spawn_executable, socat}, [
        :binary,
        :exit_status,
        :stderr_to_stdout,
        args: ["-d", "-d", "pty,raw,echo=0,link=#{a}", "pty,raw,echo=0,link=#{b}"]
      ])

    {:os_pid, os_pid} = Port.info(port, :os_pid)

    ExUnit.Callbacks.on_exit(fn ->
      kill_os_pid(os_pid)
      File.rm_rf(dir)
    end)

    wait_until(fn -> File.exists?(a) and File.exists?(b) end, "socat links #{a} #{b}")
    %{dir: dir, a: a, b: b, port: port, os_pid: os_pid}
  end

  @doc "Kills socat: both ends hang up and their links disappear."
  @spec hang_up!(pair()) :: :ok
  def hang_up!(%{os_pid: os_pid, a: a, b: b}) do
    kill_os_pid(os_pid)
    wait_until(fn -> not File.exists?(a) and not File.exists?(b) end, "socat gone")
  end

  defp kill_os_pid(os_pid) do
    System.cmd("kill", ["-TERM", Integer.to_string(os_pid)], stderr_to_stdout: true)
    true
  end

  @doc "Opens `device` with the port program; returns the port once the device is open."
  @spec open!(String.t(), pos_integer()) :: port()
  def open!(device, baud \\ 115_200) do
    port =
      Port.open({:spawn_executable, UART.program()}, [
        :binary,
        {:packet, 2},
        :exit_status,
        args: ["tty", device, Integer.to_string(baud)]
      ])

    receive do
      {^port, {:data, "o" <> _}} -> port
      {^port, {:data, "e" <> why}} -> flunk("cannot open #{device}: #{why}")
    after
      Patience.ms() -> flunk("#{device} did not open")
    end
  end

  @doc "Writes bytes on a line opened with `open!/1`."
  @spec write(port(), iodata()) :: true
  def write(port, bytes), do: Port.command(port, ["w", bytes])

  @doc """
  Reads from the line until `done?.(bytes_so_far)` is true; returns all bytes read. Fails the
  test after `timeout` ms (`Neptunus.Test.Patience`).
  """
  @spec recv_until(port(), (binary() -> boolean()), timeout()) :: binary()
  def recv_until(port, done?, timeout \\ Patience.ms()) do
    deadline = System.monotonic_time(:millisecond) + timeout
    do_recv(port, done?, "", deadline)
  end

  defp do_recv(port, done?, acc, deadline) do
    if done?.(acc) do
      acc
    else
      left = max(deadline - System.monotonic_time(:millisecond), 0)

      receive do
        {^port, {:data, "r" <> bytes}} -> do_recv(port, done?, acc <> bytes, deadline)
      after
        left -> flunk("timed out; read so far: #{inspect(acc)}")
      end
    end
  end

  @doc "Reads whatever arrives within `ms`."
  @spec drain(port(), non_neg_integer()) :: binary()
  def drain(port, ms) do
    receive do
      {^port, {:data, "r" <> bytes}} -> bytes <> drain(port, ms)
    after
      ms -> ""
    end
  end

  @doc """
  Polls `fun` every 10 ms until it returns truthy (fails after `timeout` ms,
  `Neptunus.Test.Patience`).
  """
  @spec wait_until((() -> term()), String.t(), timeout()) :: term()
  def wait_until(fun, what, timeout \\ Patience.ms()) do
    deadline = System.monotonic_time(:millisecond) + timeout
    do_wait(fun, what, deadline)
  end

  defp do_wait(fun, what, deadline) do
    cond do
      result = fun.() ->
        result

      System.monotonic_time(:millisecond) > deadline ->
        flunk("timed out waiting for #{what}")

      true ->
        Process.sleep(10)
        do_wait(fun, what, deadline)
    end
  end
end
