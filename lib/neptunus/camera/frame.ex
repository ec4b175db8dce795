defmodule Neptunus.Camera.Frame do
  @moduledoc """
  One video frame as it goes to every viewer (pure): the 28-byte header of the video
  WebSocket's binary messages (docs/API.md, "Video") followed by the picture, built once
  per frame. Every viewer gets this same binary (behind its WebSocket frame header), so a
  frame is never copied or encoded per viewer.

      offset size  field
      0      1     version = 1
      1      1     kind: 1 H.264 access unit (Annex B), 2 JPEG image
      2      1     flags: bit 0 keyframe, bit 1 first frame of a new generation
      3      1     reserved (0)
      4      4     generation (uint32 BE)
      8      4     sequence number within the generation (uint32 BE)
      12     8     server arrival time, wall-clock µs since the epoch (uint64 BE)
      20     8     capture/render time, wall-clock µs (uint64 BE), 0 when unknown
      28     …     payload

  What the camera publishes for each frame is `t:t/0`: the binary and what viewers decide
  by (keyframe, generation, sequence) without reading it.
  """

  import Bitwise

  @version 1
  @header_bytes 28

  @typedoc """
  * `data` — header and payload, the bytes every viewer sends
  * `keyframe` — a decoder can start here (an IDR picture with SPS and PPS in front, or
    any JPEG)
  * `generation`, `seq` — as in the header
  """
  @type t :: %__MODULE__{
          data: binary(),
          keyframe: boolean(),
          generation: non_neg_integer(),
          seq: non_neg_integer()
        }
  @enforce_keys [:data, :keyframe, :generation, :seq]
  defstruct [:data, :keyframe, :generation, :seq]

  @type kind :: :h264 | :jpeg

  @doc "The header's size in bytes."
  @spec header_bytes() :: pos_integer()
  def header_bytes, do: @header_bytes

  @doc """
  Builds a frame. Options: `:keyframe`, `:first` (first of its generation), `:generation`,
  `:seq`, `:arrival_us`, `:capture_us` (default 0).

      iex> frame = Neptunus.Camera.Frame.new(:h264, <<0, 0, 0, 1, 0x65>>,
      ...>   keyframe: true, first: true, generation: 7, seq: 0, arrival_us: 5, capture_us: 3)
      iex> frame.data
      <<1, 1, 3, 0, 7::32, 0::32, 5::64, 3::64, 0, 0, 0, 1, 0x65>>
  """
  @spec new(kind(), iodata(), keyword()) :: t()
  def new(kind, payload, opts) do
    keyframe = Keyword.fetch!(opts, :keyframe)
    generation = Keyword.fetch!(opts, :generation)
    seq = Keyword.fetch!(opts, :seq)
    flags = if(keyframe, do: 1, else: 0) ||| if(Keyword.get(opts, :first, false), do: 2, else: 0)

    header =
      <<@version, kind_byte(kind), flags, 0, generation &&& 0xFFFFFFFF::32,
        seq &&& 0xFFFFFFFF::32, Keyword.fetch!(opts, :arrival_us)::64,
        Keyword.get(opts, :capture_us, 0)::64>>

    %__MODULE__{
      data: IO.iodata_to_binary([header, payload]),
      keyframe: keyframe,
      generation: generation,
      seq: seq
    }
  end

  defp kind_byte(:h264), do: 1
  defp kind_byte(:jpeg), do: 2

  @doc "The payload of a frame's binary (a sub-binary: nothing is copied)."
  @spec payload(t() | binary()) :: binary()
  def payload(%__MODULE__{data: data}), do: payload(data)
  def payload(<<_::binary-size(@header_bytes), payload::binary>>), do: payload

  @doc """
  Reads a frame's header (for tests and tools).

      iex> frame = Neptunus.Camera.Frame.new(:jpeg, "x", keyframe: true, generation: 1, seq: 2, arrival_us: 3)
      iex> Neptunus.Camera.Frame.parse(frame.data)
      {:ok, %{kind: :jpeg, keyframe: true, first: false, generation: 1, seq: 2, arrival_us: 3,
              capture_us: 0, payload: "x"}}
  """
  @spec parse(binary()) :: {:ok, map()} | {:error, String.t()}
  def parse(
        <<@version, kind, flags, _reserved, generation::32, seq::32, arrival::64, capture::64,
          payload::binary>>
      )
      when kind in [1, 2] do
    {:ok,
     %{
       kind: if(kind == 1, do: :h264, else: :jpeg),
       keyframe: (flags &&& 1) == 1,
       first: (flags &&& 2) == 2,
       generation: generation,
       seq: seq,
       arrival_us: arrival,
       capture_us: capture,
       payload: payload
     }}
  end

  def parse(_data), do: {:error, "not a version 1 video frame"}
end
