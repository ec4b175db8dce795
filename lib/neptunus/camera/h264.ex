defmodule Neptunus.Camera.H264 do
  @moduledoc """
  H.264 (ITU-T H.264 / ISO 14496-10), pure: NAL units, Annex B byte streams cut into NAL
  units and access units (one picture each), and what a player needs from the sequence
  parameter set (SPS): the picture size and the RFC 6381 codec string (`avc1.PPCCLL`).

  ## Annex B

  A byte stream of NAL units, each after a start code `00 00 01` (or `00 00 00 01`). A NAL
  unit never contains `00 00 00`, `00 00 01` or `00 00 02` (the encoder inserts an emulation
  prevention byte `03`), so the next start code ends it; the zero bytes before a start code
  belong to it, not to the NAL unit before (`trailing_zero_8bits`).

  `split/2` returns the NAL units whose end has been seen; the last one stays in the rest
  until the next start code (or `flush/1` at the end of the stream). Told how much of the
  rest it has scanned before, it does not scan it again.

  ## Access units

  `AccessUnits` (below) groups NAL units into access units by the rules of H.264 §7.4.1.2.3
  as a decoder's first pass sees them: an access unit delimiter (9), SPS (7), PPS (8), SEI
  (6) or types 14–18 after a picture's slices start a new access unit, and so does a slice
  (1 or 5) whose `first_mb_in_slice` is 0 (the first slice of a new picture: its first bit
  after the NAL header is 1, `ue(v)` of 0). A picture is known complete only when the next
  one starts — as soon as the next one's first NAL unit shows its first two bytes
  (`AccessUnits.next/2`).
  """

  import Bitwise

  @typedoc "A NAL unit without start code: its header byte, then its payload (escaped)."
  @type nal :: binary()

  @typedoc "What the SPS tells: profile, constraint flags and level (bytes 1–3), the size."
  @type sps_info :: %{
          profile_idc: byte(),
          constraints: byte(),
          level_idc: byte(),
          width: pos_integer(),
          height: pos_integer(),
          fps: float() | nil
        }

  @doc """
  The type of a NAL unit (`nal_unit_type`, 0..31): 1 slice, 5 IDR slice, 6 SEI, 7 SPS,
  8 PPS, 9 access unit delimiter, …

      iex> Neptunus.Camera.H264.type(<<0x65, 0x88>>)
      5
  """
  @spec type(nal()) :: 0..31
  def type(<<_::3, type::5, _::binary>>), do: type

  @doc "Whether a NAL unit is a slice of a picture (VCL: types 1..5)."
  @spec slice?(nal()) :: boolean()
  def slice?(nal), do: type(nal) in 1..5

  @doc "Whether NAL units (one access unit) hold an IDR picture: a decoder can start there."
  @spec keyframe?([nal()]) :: boolean()
  def keyframe?(nals), do: Enum.any?(nals, &(type(&1) == 5))

  @doc """
  NAL units as Annex B (4-byte start codes), iodata.

      iex> IO.iodata_to_binary(Neptunus.Camera.H264.annexb([<<0x67, 1>>, <<0x68, 2>>]))
      <<0, 0, 0, 1, 0x67, 1, 0, 0, 0, 1, 0x68, 2>>
  """
  @spec annexb([nal()]) :: iodata()
  def annexb(nals), do: Enum.map(nals, &[<<0, 0, 0, 1>>, &1])

  @doc """
  Cuts an Annex B `buffer` (the rest of the previous call followed by new bytes) into the
  NAL units complete in it, the rest to keep (from the last start code on), and the number
  of bytes skipped (before the first start code: not H.264). `scanned`: the size of the
  rest given back by the previous call (searched already: no start code in it but its first).

      iex> Neptunus.Camera.H264.split(<<9, 0, 0, 1, 0x67, 1, 0, 0, 0, 1, 0x68, 2, 0, 0, 1, 0x65>>)
      {[<<0x67, 1>>, <<0x68, 2>>], <<0, 0, 1, 0x65>>, 1}
  """
  @spec split(binary(), non_neg_integer()) :: {[nal()], binary(), non_neg_integer()}
  def split(buffer, scanned \\ 0) when is_binary(buffer) do
    case :binary.match(buffer, <<0, 0, 1>>) do
      :nomatch ->
        # keep up to three trailing zeros: they may begin a (4-byte) start code
        keep = trailing_zeros(buffer, 3)
        {[], binary_part(buffer, byte_size(buffer) - keep, keep), byte_size(buffer) - keep}

      {start, 3} ->
        # the zero of a 4-byte start code is part of the start code, not junk
        lead = if start > 0 and :binary.at(buffer, start - 1) == 0, do: 1, else: 0
        {nals, rest} = nals(buffer, start + 3, max(start + 3, scanned - 2), start - lead, [])
        {nals, rest, start - lead}
    end
  end

  # NAL units from `from` (after a start code), the next start code searched from `search`;
  # `mark` is where the start code before `from` begins.
  defp nals(buffer, from, search, mark, acc) do
    case :binary.match(buffer, <<0, 0, 1>>, scope: {search, byte_size(buffer) - search}) do
      :nomatch ->
        {Enum.reverse(acc), binary_part(buffer, mark, byte_size(buffer) - mark)}

      {next, 3} ->
        nal = buffer |> binary_part(from, next - from) |> strip_trailing_zeros()

        acc = if nal == <<>>, do: acc, else: [nal | acc]

        nals(
          buffer,
          next + 3,
          next + 3,
          next - trailing_zeros(binary_part(buffer, 0, next), 1),
          acc
        )
    end
  end

  @doc """
  The NAL unit left in `split/1`'s rest at the end of a stream (nil when there is none).
  """
  @spec flush(binary()) :: nal() | nil
  def flush(rest) do
    case split(rest <> <<0, 0, 1>>) do
      {[nal], _, _} -> nal
      _ -> nil
    end
  end

  defp trailing_zeros(bin, max), do: trailing_zeros(bin, byte_size(bin), max, 0)

  defp trailing_zeros(_bin, 0, _max, n), do: n
  defp trailing_zeros(_bin, _size, max, n) when n == max, do: n

  defp trailing_zeros(bin, size, max, n) do
    if :binary.at(bin, size - 1) == 0, do: trailing_zeros(bin, size - 1, max, n + 1), else: n
  end

  defp strip_trailing_zeros(nal) do
    size = byte_size(nal)
    n = trailing_zeros(nal, size, size, 0)
    binary_part(nal, 0, size - n)
  end

  @doc """
  Whether `nal` begins a new access unit after an access unit that already holds `slice?`
  (a slice of its picture): see "Access units".
  """
  @spec starts_access_unit?(nal(), boolean()) :: boolean()
  def starts_access_unit?(nal, slice?) do
    case type(nal) do
      t when t in [6, 7, 8, 9] or t in 14..18 -> slice?
      t when t in 1..5 -> slice? and first_slice?(nal)
      _ -> false
    end
  end

  # first_mb_in_slice == 0: the first bit after the header is 1
  defp first_slice?(<<_header, 1::1, _::bits>>), do: true
  defp first_slice?(_nal), do: false

  @doc """
  Removes emulation prevention bytes (`00 00 03` → `00 00`): a NAL unit's raw payload.

      iex> Neptunus.Camera.H264.unescape(<<1, 0, 0, 3, 1, 0, 0, 3>>)
      <<1, 0, 0, 1, 0, 0>>
  """
  @spec unescape(binary()) :: binary()
  def unescape(bin) do
    case :binary.split(bin, <<0, 0, 3>>, [:global]) do
      [one] -> one
      parts -> Enum.join(parts, <<0, 0>>)
    end
  end

  @doc """
  The RFC 6381 codec string of a stream from its SPS: `avc1.` and the SPS's profile,
  constraint flags and level bytes in hex (what WebCodecs and MSE want).

      iex> Neptunus.Camera.H264.codec_string(<<0x67, 0x42, 0xC0, 0x1E, 0xDA>>)
      "avc1.42C01E"
  """
  @spec codec_string(nal()) :: String.t()
  def codec_string(<<_header, profile, constraints, level, _::binary>>),
    do: "avc1." <> Base.encode16(<<profile, constraints, level>>)

  @doc """
  Reads an SPS NAL unit: profile, constraints, level, the displayed picture size (after
  cropping) and, when the SPS carries timing information, the frame rate.
  `{:error, reason}` for a NAL unit that is not a well-formed SPS.
  """
  @spec sps(nal()) :: {:ok, sps_info()} | {:error, String.t()}
  def sps(<<_::3, 7::5, profile, constraints, level, rest::binary>>) do
    {:ok, parse_sps(unescape(rest), profile, constraints, level)}
  rescue
    _ in [MatchError, FunctionClauseError, ArgumentError, CaseClauseError] ->
      {:error, "a malformed SPS"}
  end

  def sps(_nal), do: {:error, "not an SPS"}

  defp parse_sps(bits, profile, constraints, level) do
    {_sps_id, bits} = ue(bits)

    {chroma_format, bits} =
      if profile in [100, 110, 122, 244, 44, 83, 86, 118, 128, 138, 139, 134, 135] do
        {chroma, bits} = ue(bits)
        bits = if chroma == 3, do: skip(bits, 1), else: bits
        {_luma_depth, bits} = ue(bits)
        {_chroma_depth, bits} = ue(bits)
        <<_qpprime::1, scaling?::1, bits::bits>> = bits

        bits =
          if scaling? == 1, do: scaling_lists(bits, if(chroma == 3, do: 12, else: 8)), else: bits

        {chroma, bits}
      else
        {1, bits}
      end

    {_log2_max_frame_num, bits} = ue(bits)
    {poc_type, bits} = ue(bits)
    bits = poc(poc_type, bits)
    {_max_ref_frames, bits} = ue(bits)
    <<_gaps::1, bits::bits>> = bits
    {width_mbs, bits} = ue(bits)
    {height_units, bits} = ue(bits)
    <<frame_mbs_only::1, bits::bits>> = bits
    bits = if frame_mbs_only == 0, do: skip(bits, 1), else: bits
    <<_direct_8x8::1, cropping::1, bits::bits>> = bits

    {{left, right, top, bottom}, bits} =
      if cropping == 1 do
        {l, bits} = ue(bits)
        {r, bits} = ue(bits)
        {t, bits} = ue(bits)
        {b, bits} = ue(bits)
        {{l, r, t, b}, bits}
      else
        {{0, 0, 0, 0}, bits}
      end

    {crop_x, crop_y} =
      case chroma_format do
        0 -> {1, 2 - frame_mbs_only}
        1 -> {2, 2 * (2 - frame_mbs_only)}
        2 -> {2, 2 - frame_mbs_only}
        3 -> {1, 2 - frame_mbs_only}
      end

    width = (width_mbs + 1) * 16 - crop_x * (left + right)
    height = (2 - frame_mbs_only) * (height_units + 1) * 16 - crop_y * (top + bottom)
    if width < 1 or height < 1, do: raise(ArgumentError, "no picture")

    %{
      profile_idc: profile,
      constraints: constraints,
      level_idc: level,
      width: width,
      height: height,
      fps: vui_fps(bits)
    }
  end

  defp poc(0, bits) do
    {_log2_max_poc_lsb, bits} = ue(bits)
    bits
  end

  defp poc(1, bits) do
    <<_delta_always_zero::1, bits::bits>> = bits
    {_, bits} = se(bits)
    {_, bits} = se(bits)
    {cycle, bits} = ue(bits)
    Enum.reduce(List.duplicate(nil, cycle), bits, fn _, bits -> bits |> se() |> elem(1) end)
  end

  defp poc(2, bits), do: bits

  defp scaling_lists(bits, count) do
    Enum.reduce(0..(count - 1), bits, fn i, bits ->
      <<present::1, bits::bits>> = bits
      if present == 1, do: scaling_list(bits, if(i < 6, do: 16, else: 64), 8, 8), else: bits
    end)
  end

  defp scaling_list(bits, 0, _last, _next), do: bits

  defp scaling_list(bits, n, last, next) do
    if next == 0 do
      scaling_list(bits, n - 1, last, 0)
    else
      {delta, bits} = se(bits)
      next = rem(last + delta + 256, 256)
      scaling_list(bits, n - 1, if(next == 0, do: last, else: next), next)
    end
  end

  # The frame rate from the VUI's timing information, if present (else nil).
  defp vui_fps(<<1::1, bits::bits>>) do
    <<aspect?::1, bits::bits>> = bits

    bits =
      case aspect? do
        1 ->
          <<idc::8, bits::bits>> = bits
          if idc == 255, do: skip(bits, 32), else: bits

        0 ->
          bits
      end

    <<overscan?::1, bits::bits>> = bits
    bits = if overscan? == 1, do: skip(bits, 1), else: bits
    <<video_signal?::1, bits::bits>> = bits

    bits =
      if video_signal? == 1 do
        <<_format::3, _full::1, colour?::1, bits::bits>> = bits
        if colour? == 1, do: skip(bits, 24), else: bits
      else
        bits
      end

    <<chroma_loc?::1, bits::bits>> = bits

    bits =
      if chroma_loc? == 1 do
        {_, bits} = ue(bits)
        {_, bits} = ue(bits)
        bits
      else
        bits
      end

    case bits do
      <<1::1, units::32, scale::32, _::bits>> when units > 0 and scale > 0 ->
        # a frame is two fields: time_scale / (2 · num_units_in_tick)
        Float.round(scale / (2 * units), 3)

      _ ->
        nil
    end
  end

  defp vui_fps(_bits), do: nil

  defp skip(bits, n) do
    <<_::size(n), rest::bits>> = bits
    rest
  end

  # Exp-Golomb: unsigned ue(v) and signed se(v)
  defp ue(bits), do: ue(bits, 0)

  defp ue(<<0::1, rest::bits>>, zeros) when zeros < 32, do: ue(rest, zeros + 1)

  defp ue(<<1::1, rest::bits>>, zeros) do
    <<value::size(zeros), rest::bits>> = rest
    {(1 <<< zeros) - 1 + value, rest}
  end

  defp se(bits) do
    {k, rest} = ue(bits)
    {if(rem(k, 2) == 1, do: div(k + 1, 2), else: -div(k, 2)), rest}
  end

  defmodule AccessUnits do
    @moduledoc """
    NAL units grouped into access units as they arrive (pure; see `Neptunus.Camera.H264`,
    "Access units"). `push/2` takes the next NAL unit and returns the access unit it
    completed, if any: the pending one, when this NAL unit starts the next.
    """
    alias Neptunus.Camera.H264

    @typedoc "The NAL units of the access unit in progress (newest first); whether it has a slice."
    @type t :: %__MODULE__{nals: [H264.nal()], slice?: boolean()}
    defstruct nals: [], slice?: false

    @doc "No access unit in progress."
    @spec new() :: t()
    def new, do: %__MODULE__{}

    @doc "Adds `nal`; returns the access unit it completed (its NAL units in order) or nil."
    @spec push(t(), H264.nal()) :: {t(), [H264.nal()] | nil}
    def push(%__MODULE__{} = au, nal) do
      if H264.starts_access_unit?(nal, au.slice?) do
        {%__MODULE__{nals: [nal], slice?: H264.slice?(nal)}, Enum.reverse(au.nals)}
      else
        {%__MODULE__{nals: [nal | au.nals], slice?: au.slice? or H264.slice?(nal)}, nil}
      end
    end

    @doc """
    Looks at the beginning of the next NAL unit (`head`: its first bytes, at least its header
    and the next; the rest of it not arrived yet): if it starts a new access unit, the one in
    progress is complete now — returned, and no longer in progress — rather than when the
    next NAL unit ends.
    """
    @spec next(t(), binary()) :: {t(), [H264.nal()] | nil}
    def next(%__MODULE__{} = au, <<_, _, _::binary>> = head) do
      if H264.starts_access_unit?(head, au.slice?),
        do: {new(), Enum.reverse(au.nals)},
        else: {au, nil}
    end

    def next(au, _head), do: {au, nil}

    @doc "The access unit in progress, if it holds a picture (end of stream)."
    @spec flush(t()) :: {t(), [H264.nal()] | nil}
    def flush(%__MODULE__{slice?: true} = au), do: {new(), Enum.reverse(au.nals)}
    def flush(au), do: {au, nil}
  end
end
