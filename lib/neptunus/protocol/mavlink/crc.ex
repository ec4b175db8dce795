defmodule Neptunus.Protocol.MAVLink.CRC do
  @moduledoc """
  The MAVLink checksum: CRC-16/MCRF4XX, which MAVLink calls X.25 (reflected polynomial
  0x8408, initial value 0xFFFF, no final XOR). A frame's checksum covers every byte after the
  start byte up to the end of the payload, then the message's CRC_EXTRA byte; it goes on the
  wire little-endian. Table-driven (one lookup per byte).
  """

  import Bitwise

  @table (for n <- 0..255 do
            Enum.reduce(1..8, n, fn _, crc ->
              if (crc &&& 1) == 1, do: bxor(crc >>> 1, 0x8408), else: crc >>> 1
            end)
          end)
         |> List.to_tuple()

  @doc """
  Accumulates `bytes` into a running checksum (0xFFFF to start).

      iex> Neptunus.Protocol.MAVLink.CRC.x25("123456789")
      0x6F91
  """
  @spec x25(binary(), 0..0xFFFF) :: 0..0xFFFF
  def x25(bytes, crc \\ 0xFFFF), do: accumulate(bytes, crc)

  defp accumulate(<<byte, rest::binary>>, crc),
    do: accumulate(rest, bxor(crc >>> 8, elem(@table, bxor(crc, byte) &&& 0xFF)))

  defp accumulate(<<>>, crc), do: crc
end
