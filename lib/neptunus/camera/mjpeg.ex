defmodule Neptunus.Camera.MJPEG do
  @moduledoc """
  Motion JPEG, pure: cutting a camera program's byte stream (JPEG images one after the
  other, as `ffmpeg -f mjpeg` writes them) into frames, and the parts of the
  `multipart/x-mixed-replace` stream browsers show in an `<img>`.

  Frames are found by walking the JPEG's marker segments, not by searching for the end
  marker `FF D9`: those two bytes may appear inside a segment (an ICC profile, a thumbnail),
  and only the entropy-coded data after a start-of-scan is scanned byte-wise (where `FF` is
  always followed by `00`, a restart marker or the next marker). Bytes before a frame's
  start (`FF D8`), a malformed frame and a frame growing past `max_bytes` are skipped and
  counted; the stream resynchronises at the next start of image.
  """

  @soi <<0xFF, 0xD8>>

  @typedoc "What `split/2` keeps between calls: the bytes of a frame not yet complete."
  @type rest :: binary()

  @doc """
  Splits `buffer` (what is left from the previous call followed by new bytes) into complete
  frames, the incomplete rest to keep, and the number of bytes skipped.

      iex> frame = <<0xFF, 0xD8, 0xFF, 0xDA, 0, 2, 1, 2, 0xFF, 0x00, 3, 0xFF, 0xD9>>
      iex> Neptunus.Camera.MJPEG.split("junk" <> frame <> binary_part(frame, 0, 5))
      {[<<0xFF, 0xD8, 0xFF, 0xDA, 0, 2, 1, 2, 0xFF, 0x00, 3, 0xFF, 0xD9>>], <<0xFF, 0xD8, 0xFF, 0xDA, 0>>, 4}
  """
  @spec split(binary(), pos_integer()) :: {[binary()], rest(), non_neg_integer()}
  def split(buffer, max_bytes \\ 4_000_000) when is_binary(buffer),
    do: split(buffer, max_bytes, [], 0)

  defp split(buffer, max_bytes, frames, skipped) do
    case :binary.match(buffer, @soi) do
      :nomatch ->
        # keep a trailing FF: it may be the first byte of the next start of image
        {keep, drop} = if :binary.last(<<0>> <> buffer) == 0xFF, do: {1, 1}, else: {0, 0}
        rest = binary_part(buffer, byte_size(buffer) - keep, keep)
        {Enum.reverse(frames), rest, skipped + byte_size(buffer) - drop}

      {start, _} ->
        frame_area = binary_part(buffer, start, byte_size(buffer) - start)

        case walk(frame_area, 2) do
          {:frame, len} ->
            frame = binary_part(frame_area, 0, len)
            after_frame = binary_part(frame_area, len, byte_size(frame_area) - len)
            split(after_frame, max_bytes, [frame | frames], skipped + start)

          :more when byte_size(frame_area) > max_bytes ->
            # a frame larger than anything a camera sends: resynchronise after its start
            resync(frame_area, max_bytes, frames, skipped + start)

          :more ->
            {Enum.reverse(frames), frame_area, skipped + start}

          :bad ->
            resync(frame_area, max_bytes, frames, skipped + start)
        end
    end
  end

  defp resync(frame_area, max_bytes, frames, skipped) do
    tail = binary_part(frame_area, 2, byte_size(frame_area) - 2)
    split(tail, max_bytes, frames, skipped + 2)
  end

  # At offset i a marker is expected. {:frame, length} at the end of image.
  defp walk(buf, i) when byte_size(buf) < i + 2, do: :more

  defp walk(buf, i) do
    case buf do
      <<_::binary-size(i), 0xFF, 0xFF, _::binary>> ->
        # fill byte before a marker
        walk(buf, i + 1)

      <<_::binary-size(i), 0xFF, 0xD9, _::binary>> ->
        {:frame, i + 2}

      <<_::binary-size(i), 0xFF, 0xD8, _::binary>> ->
        # a new start of image inside this one: this one is broken
        :bad

      <<_::binary-size(i), 0xFF, m, _::binary>> when m in 0xD0..0xD7 or m == 0x01 ->
        walk(buf, i + 2)

      <<_::binary-size(i), 0xFF, 0xDA, len::16, _::binary>> when len >= 2 ->
        entropy(buf, i + 2 + len)

      <<_::binary-size(i), 0xFF, m, len::16, _::binary>> when m != 0x00 and len >= 2 ->
        walk(buf, i + 2 + len)

      <<_::binary-size(i), 0xFF, _m>> ->
        :more

      <<_::binary-size(i), 0xFF, _m, _::binary>> when byte_size(buf) < i + 4 ->
        :more

      _ ->
        :bad
    end
  end

  # entropy-coded data from j: the next FF not followed by 00 or a restart marker is a marker
  defp entropy(buf, j) when j >= byte_size(buf), do: :more

  defp entropy(buf, j) do
    case :binary.match(buf, <<0xFF>>, scope: {j, byte_size(buf) - j}) do
      :nomatch ->
        :more

      {k, 1} when k + 1 >= byte_size(buf) ->
        :more

      {k, 1} ->
        case :binary.at(buf, k + 1) do
          0x00 -> entropy(buf, k + 2)
          m when m in 0xD0..0xD7 -> entropy(buf, k + 2)
          0xFF -> entropy(buf, k + 1)
          _ -> walk(buf, k)
        end
    end
  end

  @doc """
  The size of a JPEG image, `{width, height}`, from its start-of-frame segment (nil when
  it has none before its scan).

      iex> Neptunus.Camera.MJPEG.size(<<0xFF, 0xD8, 0xFF, 0xC0, 0, 11, 8, 360::16, 640::16, 1, 1, 0x11, 0>>)
      {640, 360}
  """
  @spec size(binary()) :: {pos_integer(), pos_integer()} | nil
  def size(<<0xFF, 0xD8, rest::binary>>), do: sof(rest)
  def size(_jpeg), do: nil

  # the start-of-frame markers C0..CF but DHT (C4), JPG (C8) and DAC (CC)
  defp sof(<<0xFF, m, _len::16, _precision, h::16, w::16, _::binary>>)
       when m in 0xC0..0xCF and m not in [0xC4, 0xC8, 0xCC] and w > 0 and h > 0,
       do: {w, h}

  defp sof(<<0xFF, 0xFF, rest::binary>>), do: sof(<<0xFF, rest::binary>>)

  defp sof(<<0xFF, m, len::16, rest::binary>>) when m != 0xDA and len >= 2 do
    case rest do
      <<_::binary-size(len - 2), rest::binary>> -> sof(rest)
      _ -> nil
    end
  end

  defp sof(_rest), do: nil

  @doc "The boundary of our `multipart/x-mixed-replace` stream."
  @spec boundary() :: String.t()
  def boundary, do: "neptunusframe"

  @doc "The `Content-Type` of the stream."
  @spec content_type() :: String.t()
  def content_type, do: "multipart/x-mixed-replace; boundary=" <> boundary()

  @doc """
  One frame as a part of the stream (iodata).

      iex> IO.iodata_to_binary(Neptunus.Camera.MJPEG.part(<<1, 2, 3>>))
      "--neptunusframe\\r\\nContent-Type: image/jpeg\\r\\nContent-Length: 3\\r\\n\\r\\n" <> <<1, 2, 3>> <> "\\r\\n"
  """
  @spec part(binary()) :: iodata()
  def part(frame) when is_binary(frame) do
    [
      "--",
      boundary(),
      "\r\nContent-Type: image/jpeg\r\nContent-Length: ",
      Integer.to_string(byte_size(frame)),
      "\r\n\r\n",
      frame,
      "\r\n"
    ]
  end
end
