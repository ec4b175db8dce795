defmodule Neptunus.Vehicle.Board.SerialPort do
  @moduledoc """
  The one Elixir owner of our serial port program, `priv/neptunus_uart`
  (`c_src/neptunus_uart.c`): how it is started, its tag protocol both ways and its exit.
  The program owns the line's file descriptor and its `poll()` loop, so nothing in the VM
  ever blocks on a tty. Its users — the OpenROV board link
  (`Neptunus.Vehicle.Board.OpenROV.UART`), the SITL board
  (`Neptunus.Vehicle.Board.OpenROV.SITL.Device`, on a pty) and the MAVLink board's serial link
  (`Neptunus.Vehicle.Board.MAVLink`) — open it here, write with `write/2` and hand every
  message of the port to `decode/1`, which turns it into a plain term (`t:event/0`); none of
  them knows a tag byte.

  The port belongs to the process that opens it (it is linked to it, and gets its messages):
  this module holds no state and starts no process.

  ## The protocol

  Every message either way is a `{packet, 2}` frame whose first byte is a tag:

    * to the program: `w` DATA — write DATA to the line (the program queues what the line does
      not take at once, up to 64 KB, and drops a write beyond that, telling `d`);
    * from it: `o` PATH (the line is open; for a pty the slave end's path), `O` (pty: someone
      opened the slave end), `r` DATA (bytes read), `t` NS (with `rx_stamps`: the
      CLOCK_MONOTONIC time of the next `r`'s read, ns), `d` N (N bytes of a write dropped),
      `s` "rx=N tx=N dropped=N queued=N" (counters), `e` TEXT (what went wrong; it exits
      right after).

  ## Its exit

  The program exits when its stdin closes (`close/1`, or the owner dies: after flushing
  what it queued, briefly), and on failure with a status `exit_reason/1` names: 64 usage,
  65 unsupported baud rate, 66 open or configure failed, 67 the line hung up (unplugged, the
  pty closed), 68 I/O error, 69 a malformed frame from the VM, 70 its stdin or stdout
  failed. The `e` frame before it says why in words. A port closed before its exit status
  reached the VM (a write to a program that had just ended) sends its owner, trapping exits,
  only `{:EXIT, port, reason}`: the owner treats that as an exit too.
  """

  @typedoc "A message of the program, as `decode/1` gives it."
  @type event ::
          {:open, path :: String.t()}
          | :peer_opened
          | {:read, binary()}
          | {:read_at_ns, integer()}
          | {:dropped, non_neg_integer()}
          | {:counters, %{String.t() => non_neg_integer()}}
          | {:error, String.t()}
          | {:exit, status :: non_neg_integer()}
          | {:unknown, binary()}

  @typedoc """
  Options of `open_tty/3` and `open_pty/2`: `:program` (the path, default `program/0`),
  `:env` (extra environment, e.g. `Neptunus.OS.port_env/1`'s time slice), `:rx_stamps`
  (`true`: a `{:read_at_ns, ns}` before every `{:read, bytes}`).
  """
  @type option ::
          {:program, String.t()} | {:env, [{charlist(), charlist()}]} | {:rx_stamps, boolean()}

  # the rates the program sets (c_src/neptunus_uart.c), and the one a line has unless told
  @bauds [1200, 2400, 4800, 9600, 19_200, 38_400, 57_600, 115_200, 230_400, 460_800, 921_600]
  @default_baud 115_200

  @doc """
  A serial line as a board's spec names it, `DEVICE[@BAUD]` (`uart:DEVICE[@BAUD]`,
  `mavlink:serial:DEVICE[@BAUD]`): an absolute device path and a rate the program sets
  (1200 … 921600, default 115200); `{:error, why}` otherwise. Pure.

      iex> alias Neptunus.Vehicle.Board.SerialPort
      iex> SerialPort.parse_line("/dev/ttyO1@57600")
      {:ok, "/dev/ttyO1", 57600}
      iex> SerialPort.parse_line("/dev/ttyACM0")
      {:ok, "/dev/ttyACM0", 115200}
      iex> SerialPort.parse_line("ttyO1")
      {:error, "the device must be an absolute path such as /dev/ttyO1"}
  """
  @spec parse_line(String.t()) :: {:ok, String.t(), pos_integer()} | {:error, String.t()}
  def parse_line(text) when is_binary(text) do
    {device, baud} =
      case String.split(text, "@") do
        [device] -> {device, Integer.to_string(@default_baud)}
        [device, baud] -> {device, baud}
        _ -> {"", ""}
      end

    cond do
      not String.starts_with?(device, "/") ->
        {:error, "the device must be an absolute path such as /dev/ttyO1"}

      match?({rate, ""} when rate in @bauds, Integer.parse(baud)) ->
        {:ok, device, String.to_integer(baud)}

      true ->
        {:error, "the baud rate must be one of #{Enum.join(@bauds, ", ")}"}
    end
  end

  @doc "Path of the port program."
  @spec program() :: String.t()
  def program, do: Application.app_dir(:neptunus, "priv/neptunus_uart")

  @doc """
  Starts the program on serial device `device` at `baud` (raw 8N1), owned by the caller.
  `{:error, why}` when the program cannot be started; a device that cannot be opened is
  told later, as `{:error, text}` then `{:exit, 66}`.
  """
  @spec open_tty(String.t(), pos_integer(), [option()]) :: {:ok, port()} | {:error, String.t()}
  def open_tty(device, baud, opts \\ []) when is_binary(device) and is_integer(baud),
    do: spawn_program(["tty", device, Integer.to_string(baud)], opts)

  @doc """
  Starts the program making a pseudo-terminal pair, its slave end symlinked at `link` (the
  simulated board's side: the program speaks on the master end), owned by the caller.
  """
  @spec open_pty(String.t(), [option()]) :: {:ok, port()} | {:error, String.t()}
  def open_pty(link, opts \\ []) when is_binary(link), do: spawn_program(["pty", link], opts)

  defp spawn_program(args, opts) do
    stamps = if opts[:rx_stamps], do: [{~c"NEPTUNUS_UART_RX_STAMPS", ~c"1"}], else: []

    port =
      Port.open({:spawn_executable, Keyword.get(opts, :program) || program()}, [
        :binary,
        {:packet, 2},
        :exit_status,
        :use_stdio,
        {:env, stamps ++ Keyword.get(opts, :env, [])},
        args: args
      ])

    {:ok, port}
  rescue
    error -> {:error, Exception.message(error)}
  end

  @doc """
  Waits (in the owner) until the program says the line is open: `{:ok, path}`, or why not —
  its error text, its exit, or `:timeout` after `timeout` ms. Only those messages are taken
  from the mailbox.
  """
  @spec await_open(port(), timeout()) :: {:ok, String.t()} | {:error, String.t() | :timeout}
  def await_open(port, timeout) when is_port(port) do
    receive do
      {^port, {:data, <<?o, path::binary>>}} -> {:ok, path}
      {^port, {:data, <<?e, why::binary>>}} -> {:error, why}
      {^port, {:exit_status, status}} -> {:error, "port program exited with status #{status}"}
    after
      timeout -> {:error, :timeout}
    end
  end

  @doc """
  Writes `bytes` to the line, never blocking: `{:error, :busy}` when the program's input is
  full (the write is dropped), `{:error, :closed}` when the port is gone.
  """
  @spec write(port(), iodata()) :: :ok | {:error, :busy | :closed}
  def write(port, bytes) when is_port(port) do
    if :erlang.port_command(port, [?w, bytes], [:nosuspend]), do: :ok, else: {:error, :busy}
  catch
    :error, :badarg -> {:error, :closed}
  end

  @doc "Closes the port: the program flushes what it queued (briefly) and exits with status 0."
  @spec close(port()) :: :ok
  def close(port) when is_port(port) do
    Port.close(port)
    :ok
  catch
    :error, :badarg -> :ok
  end

  @doc """
  A message of the port (`{port, message}`'s `message`) as a plain term.

      iex> alias Neptunus.Vehicle.Board.SerialPort
      iex> SerialPort.decode({:data, "o/dev/pts/3"})
      {:open, "/dev/pts/3"}
      iex> SerialPort.decode({:data, "rdeap:1.2;"})
      {:read, "deap:1.2;"}
      iex> SerialPort.decode({:data, "d12"})
      {:dropped, 12}
      iex> SerialPort.decode({:exit_status, 67})
      {:exit, 67}
      iex> SerialPort.decode({:data, "x?"})
      {:unknown, "x?"}
  """
  @spec decode({:data, binary()} | {:exit_status, non_neg_integer()}) :: event()
  def decode({:exit_status, status}) when is_integer(status), do: {:exit, status}
  def decode({:data, <<?r, bytes::binary>>}), do: {:read, bytes}
  def decode({:data, <<?o, path::binary>>}), do: {:open, path}
  def decode({:data, "O"}), do: :peer_opened
  def decode({:data, <<?e, text::binary>>}), do: {:error, text}

  def decode({:data, <<?t, ns::binary>>} = data) do
    case Integer.parse(ns) do
      {ns, ""} -> {:read_at_ns, ns}
      _ -> unknown(data)
    end
  end

  def decode({:data, <<?d, n::binary>>} = data) do
    case Integer.parse(n) do
      {n, ""} when n >= 0 -> {:dropped, n}
      _ -> unknown(data)
    end
  end

  def decode({:data, <<?s, text::binary>>} = data) do
    pairs = for pair <- String.split(text, " ", trim: true), do: String.split(pair, "=")

    counters =
      for [key, value] <- pairs,
          {n, ""} <- [Integer.parse(value)],
          n >= 0,
          into: %{},
          do: {key, n}

    if pairs != [] and map_size(counters) == length(pairs),
      do: {:counters, counters},
      else: unknown(data)
  end

  def decode({:data, frame}) when is_binary(frame), do: {:unknown, frame}

  defp unknown({:data, frame}), do: {:unknown, frame}
end
