defmodule NeptunusWeb.Socket.WsFrame do
  @moduledoc """
  WebSocket text and binary frames from the server (RFC 6455 §5.2), as iodata: the frame
  header, then the payload binary itself.

  `NeptunusWeb.Socket` sends broadcast frames this way. A broadcast is encoded once
  (`Neptunus.PubSub`) and its binary shared by every connection that receives it; yaws'
  own send builds each frame as one new binary (header and payload copied together), so
  every connection would hold a private copy of every frame until its next garbage
  collection — most of an observer's memory. Written as `[header, payload]`, the socket
  sends the shared binary and the connection holds only the few header bytes.

  Server frames are never masked; the payload is sent whole (FIN set, opcode 1: text, or 2:
  binary — the video socket's frames, `NeptunusWeb.VideoSocket`).

      iex> NeptunusWeb.Socket.WsFrame.text("hi")
      [<<0x81, 2>>, "hi"]
      iex> [header, _] = NeptunusWeb.Socket.WsFrame.text(String.duplicate("x", 300))
      iex> header
      <<0x81, 126, 300::16>>
  """

  @fin_text 0x81
  @fin_binary 0x82
  # payload length limits of the 7-bit and 16-bit length forms
  @max_short 125
  @max_medium 0xFFFF
  @max_long 0x7FFF_FFFF_FFFF_FFFF

  @doc "A final, unmasked text frame carrying `payload` (UTF-8 text, not checked here)."
  @spec text(binary()) :: iodata()
  def text(payload) when is_binary(payload), do: [header(byte_size(payload)), payload]

  @doc """
  A final, unmasked binary frame carrying `payload`.

      iex> NeptunusWeb.Socket.WsFrame.binary(<<1, 2>>)
      [<<0x82, 2>>, <<1, 2>>]
  """
  @spec binary(binary()) :: iodata()
  def binary(payload) when is_binary(payload),
    do: [header(byte_size(payload), @fin_binary), payload]

  @doc """
  The header of a final, unmasked text frame (or, with `first_byte` 0x82, binary frame)
  whose payload is `size` bytes: 2 bytes up to #{@max_short}, 4 up to #{@max_medium}, 10
  beyond. Raises `ArgumentError` for a size no frame can carry.
  """
  @spec header(non_neg_integer(), byte()) :: binary()
  def header(size, first_byte \\ @fin_text)

  def header(size, first) when is_integer(size) and size >= 0 and size <= @max_short,
    do: <<first, size>>

  def header(size, first) when is_integer(size) and size > @max_short and size <= @max_medium,
    do: <<first, 126, size::16>>

  def header(size, first) when is_integer(size) and size > @max_medium and size <= @max_long,
    do: <<first, 127, size::64>>

  def header(size, _first),
    do: raise(ArgumentError, "a frame payload is 0..#{@max_long} bytes, got #{inspect(size)}")
end
