defmodule Neptunus.Vehicle.Board.OpenROV.SITL.Firmware.Commands do
  @moduledoc """
  The SITL firmware's serial input (`Neptunus.Vehicle.Board.OpenROV.SITL.Firmware`; the firmware's
  `Command.cpp`): the receive buffer, the command buffer, a command's CRC, echo, split and
  arguments, and the ring of internal commands. Each command goes to the devices
  (`Neptunus.Vehicle.Board.OpenROV.SITL.Firmware.Devices.handle/5`).

  **Receive buffer** (`:loop_ms`, `:stall_ms`). Bytes land in the serial receive buffer
  (64 bytes); what arrives while it is full is lost and counted in `rx_dropped`. The loop
  empties it every `loop_ms` (default 10), except that the depth sensor's conversion once a
  second (two 10 ms waits) stalls it for `stall_ms` (default 20). So a burst of more than
  64 bytes loses bytes, and a link that writes at most 60 bytes in any 30 ms loses none.

  **Commands** are read into an 80-byte command buffer up to their `;` (a command that grows
  past 80 bytes is cut and its next byte lost, as the firmware does). 2.5.2 parses the text;
  30.0.2 first checks the leading byte against the Dallas/Maxim CRC-8 of the rest (`;`
  included), prints `rawcmd:` with every byte in hex and `,` then `;\\r\\n`, then
  `crc:pass;` or `crc:fail,COMPUTED/RECEIVED;` (hex, no newline) and drops a failed command.
  A CRC byte equal to `;` ends the command at once (it then fails, and the rest is read as
  another command). An accepted command is split at spaces, commas, parentheses and `;`,
  echoed as `cmd:name(arg,arg);\\r\\n` (the arguments as received) and its arguments read as
  16-bit integers (`atoi`). A device takes a command whose name *starts with* its own word
  (the firmware's `cmp`). Internal commands (the deadman's) go through a three-slot ring that
  holds two (the oldest is overwritten; 30.0.2 prints `log: CommandBufferOverrun;\\r\\n`) and
  are announced `icmd:name(args);\\r\\n`; 2.5.2 reads the slot before advancing, 30.0.2 after,
  so they lose different commands when it overflows.
  """

  import Bitwise, only: [&&&: 2]

  alias Neptunus.Vehicle.Board.OpenROV
  alias Neptunus.Vehicle.Board.OpenROV.SITL.Firmware
  alias Neptunus.Vehicle.Board.OpenROV.SITL.Firmware.Devices

  @rx_size 64
  @cmd_size 80
  @max_args 9
  @ring 3

  @doc """
  Bytes arriving in the serial receive buffer: what fits is kept, the rest dropped (counted
  in `rx_dropped`).
  """
  @spec buffer(Firmware.t(), binary()) :: Firmware.t()
  def buffer(fw, bytes) do
    room = @rx_size - byte_size(fw.rx)
    kept = binary_part(bytes, 0, min(room, byte_size(bytes)))
    %{fw | rx: fw.rx <> kept, rx_dropped: fw.rx_dropped + byte_size(bytes) - byte_size(kept)}
  end

  @doc """
  The loop empties the receive buffer at millis `m`: its complete commands are run, in
  order; returns what they printed.
  """
  @spec drain(Firmware.t(), integer()) :: {Firmware.t(), iodata()}
  def drain(fw, m) do
    {commands, cmdbuf} = read_commands(fw.rx, fw.cmdbuf, [])
    fw = %{fw | rx: "", cmdbuf: cmdbuf, drains: fw.drains + 1}
    fw = %{fw | next_drain: next_drain(fw, m)}

    Enum.reduce(commands, {fw, []}, fn raw, {fw, out} ->
      {fw, more} = serial_command(fw, raw, m)
      {fw, [out, more]}
    end)
  end

  # the next read: a loop later, or after the depth sensor's stall if it falls in between
  defp next_drain(fw, m) do
    next = m + fw.loop_ms
    conversion = fw.timers.depth + 1001
    if conversion <= next, do: max(next, conversion + fw.stall_ms), else: next
  end

  # getSerialString: bytes up to and including ';' (2.5.2 drops the ';', 30.0.2 keeps it); a
  # command that reaches the buffer size is discarded with the byte that overflows it
  defp read_commands(<<>>, buf, acc), do: {Enum.reverse(acc), buf}

  defp read_commands(<<_byte, rest::binary>>, buf, acc) when byte_size(buf) == @cmd_size,
    do: read_commands(rest, "", acc)

  defp read_commands(<<?;, rest::binary>>, buf, acc),
    do: read_commands(rest, "", [buf <> ";" | acc])

  defp read_commands(<<byte, rest::binary>>, buf, acc),
    do: read_commands(rest, <<buf::binary, byte>>, acc)

  defp serial_command(%{profile: :openrov_25} = fw, raw, m) do
    text = binary_part(raw, 0, byte_size(raw) - 1)
    accept(fw, text, [], m)
  end

  defp serial_command(%{profile: :openrov_30} = fw, raw, m) do
    rawcmd = ["rawcmd:", for(<<b <- raw>>, do: [hex(b), ?,]), ";\r\n"]

    case OpenROV.Protocol.unframe(raw) do
      {:ok, text} ->
        accept(fw, text, [rawcmd, "crc:pass;"], m)

      {:error, {computed, received}} ->
        fail = ["crc:fail,", hex(computed), ?/, hex(received), ?;]
        {%{fw | bad_commands: fw.bad_commands + 1}, [rawcmd, fail]}
    end
  end

  defp accept(fw, text, prefix, m) do
    {name, tokens} = tokens(text)
    # without a name the firmware prints only the closing ");"
    echo = if name == "", do: ");\r\n", else: ["cmd:", name, ?(, Enum.join(tokens, ","), ");\r\n"]
    args = tokens |> Enum.take(@max_args) |> Enum.map(&atoi/1)
    {fw, out} = Devices.handle(%{fw | commands: fw.commands + 1}, name, length(tokens), args, m)
    {fw, [prefix, echo, out]}
  end

  @doc "The firmware's split of a command: `Neptunus.Vehicle.Board.OpenROV.SITL.Firmware.tokens/1`."
  @spec tokens(binary()) :: {binary(), [binary()]}
  def tokens(text) when is_binary(text), do: OpenROV.Protocol.call(text)

  @doc """
  C's `atoi` into the AVR's 16-bit `int`: `Neptunus.Vehicle.Board.OpenROV.SITL.Firmware.atoi/1`.
  """
  @spec atoi(binary()) :: integer()
  def atoi(text) when is_binary(text) do
    n =
      case Regex.run(~r/\A\s*([+-]?)(\d+)/, text) do
        [_, sign, digits] -> if(sign == "-", do: -1, else: 1) * String.to_integer(digits)
        nil -> 0
      end

    wrap16(n)
  end

  defp wrap16(n) do
    n = n &&& 0xFFFF
    if n >= 0x8000, do: n - 0x10000, else: n
  end

  defp hex(byte), do: Integer.to_string(byte, 16)

  # Internal commands ------------------------------------------------------------------------

  defp ring_empty?({_slots, head, tail}), do: head == tail

  @doc """
  A device pushes an internal command into the ring (30.0.2 tells an overrun); returns what
  was printed.
  """
  @spec push(Firmware.t(), Firmware.internal()) :: {Firmware.t(), iodata()}
  def push(fw, command) do
    {slots, head, tail} = fw.ring
    head = rem(head + 1, @ring)

    {tail, out} =
      cond do
        head != tail -> {tail, []}
        fw.profile == :openrov_30 -> {rem(tail + 1, @ring), "log: CommandBufferOverrun;\r\n"}
        true -> {rem(tail + 1, @ring), []}
      end

    {%{fw | ring: {put_elem(slots, head, command), head, tail}}, out}
  end

  defp pop(%{ring: {slots, head, tail}, profile: :openrov_25} = fw),
    do: {%{fw | ring: {slots, head, rem(tail + 1, @ring)}}, elem(slots, tail)}

  defp pop(%{ring: {slots, head, tail}} = fw) do
    tail = rem(tail + 1, @ring)
    {%{fw | ring: {slots, head, tail}}, elem(slots, tail)}
  end

  @doc "The loop runs the internal commands waiting in the ring at millis `m`, oldest first."
  @spec internal_commands(Firmware.t(), integer()) :: {Firmware.t(), iodata()}
  def internal_commands(fw, m) do
    if ring_empty?(fw.ring) do
      {fw, []}
    else
      {fw, {name, args}} = pop(fw)
      echo = ["icmd:", name, ?(, Enum.map_join(args, ",", &Integer.to_string/1), ");\r\n"]
      {fw, out} = Devices.handle(fw, name, length(args), args, m)
      {fw, more} = internal_commands(fw, m)
      {fw, [echo, out, more]}
    end
  end
end
