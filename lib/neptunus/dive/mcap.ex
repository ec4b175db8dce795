defmodule Neptunus.Dive.MCAP do
  @moduledoc """
  An MCAP writer (pure, streaming): the file format Foxglove and the robotics tools read
  (mcap.dev, format version 0). Records are written as they come; what the summary needs is
  kept small (a chunk index per chunk, counts per channel), so a dive of hours is written
  with the memory of one chunk.

      magic, Header, Schema and Channel records, Metadata,
      Chunk (uncompressed, its records' CRC-32), its Message Index records, … ,
      Data End (the CRC-32 of everything before it),
      summary: Schema, Channel, Statistics, Metadata Index, Chunk Index groups,
      Summary Offset records (one per group), Footer (the summary's CRC-32), magic

  Every integer is little-endian; a record is its opcode, its length (64-bit) and its
  content. Messages go into chunks of about `chunk_bytes` (default 1 MiB) in the order given;
  each chunk's Message Index records follow it, so a reader seeks by time and topic.

  Use: `new/1` (schemas, channels, metadata) gives the state and the file's start;
  `message/4` adds one message (and a chunk when it is full); `finish/1` the end.
  """

  import Bitwise

  @magic <<0x89, "MCAP0\r\n">>
  @default_chunk_bytes 1_048_576

  @typedoc "A schema: id (1..65535), name, encoding (`jsonschema`), data (the schema's text)."
  @type schema :: %{id: pos_integer(), name: String.t(), encoding: String.t(), data: binary()}

  @typedoc "A channel: id, its schema's id, topic, message encoding (`json`), metadata."
  @type channel :: %{
          id: non_neg_integer(),
          schema_id: non_neg_integer(),
          topic: String.t(),
          message_encoding: String.t(),
          metadata: %{optional(String.t()) => String.t()}
        }

  @typedoc "The writer's state (see the moduledoc)."
  @type t :: %__MODULE__{
          offset: non_neg_integer(),
          crc: non_neg_integer(),
          chunk_bytes: pos_integer(),
          schemas: [schema()],
          channels: [channel()],
          metadata: [{non_neg_integer(), non_neg_integer(), String.t()}],
          chunk: iodata(),
          chunk_size: non_neg_integer(),
          chunk_crc: non_neg_integer(),
          chunk_start: non_neg_integer() | nil,
          chunk_end: non_neg_integer() | nil,
          chunk_index: %{optional(non_neg_integer()) => [{non_neg_integer(), non_neg_integer()}]},
          chunk_indexes: [iodata()],
          sequence: %{optional(non_neg_integer()) => non_neg_integer()},
          counts: %{optional(non_neg_integer()) => non_neg_integer()},
          start_time: non_neg_integer() | nil,
          end_time: non_neg_integer() | nil
        }
  defstruct offset: 0,
            crc: 0,
            chunk_bytes: @default_chunk_bytes,
            schemas: [],
            channels: [],
            metadata: [],
            chunk: [],
            chunk_size: 0,
            chunk_crc: 0,
            chunk_start: nil,
            chunk_end: nil,
            chunk_index: %{},
            chunk_indexes: [],
            sequence: %{},
            counts: %{},
            start_time: nil,
            end_time: nil

  @doc """
  Starts a file: `schemas`, `channels`, `metadata` (`[{name, %{key => value}}]`), `profile`,
  `library`, `chunk_bytes`. Returns the state and the bytes to write first.
  """
  @spec new(keyword()) :: {t(), iodata()}
  def new(opts) do
    schemas = Keyword.get(opts, :schemas, [])
    channels = Keyword.get(opts, :channels, [])

    state = %__MODULE__{
      schemas: schemas,
      channels: channels,
      chunk_bytes: Keyword.get(opts, :chunk_bytes, @default_chunk_bytes)
    }

    header =
      record(0x01, [
        str(Keyword.get(opts, :profile, "")),
        str(Keyword.get(opts, :library, "neptunus"))
      ])

    {state, out} =
      emit(state, [
        @magic,
        header | Enum.map(schemas, &schema/1) ++ Enum.map(channels, &channel/1)
      ])

    Enum.reduce(Keyword.get(opts, :metadata, []), {state, out}, fn {name, map}, {state, out} ->
      rec = record(0x0C, [str(name), string_map(map)])
      at = state.offset
      {state, more} = emit(state, rec)
      {%{state | metadata: [{at, IO.iodata_length(rec), name} | state.metadata]}, [out, more]}
    end)
  end

  @doc """
  Adds a message on `channel_id` logged at `log_time` (ns since the epoch): the bytes to write
  (nothing until a chunk is full).
  """
  @spec message(t(), non_neg_integer(), non_neg_integer(), iodata()) :: {t(), iodata()}
  def message(state, channel_id, log_time, data) do
    seq = Map.get(state.sequence, channel_id, 0)
    seq32 = seq &&& 0xFFFFFFFF

    rec =
      record(0x05, [
        <<channel_id::little-16, seq32::little-32, log_time::little-64, log_time::little-64>>,
        data
      ])

    size = IO.iodata_length(rec)

    index =
      Map.update(
        state.chunk_index,
        channel_id,
        [{log_time, state.chunk_size}],
        &[{log_time, state.chunk_size} | &1]
      )

    state = %{
      state
      | chunk: [state.chunk | rec],
        chunk_crc: :erlang.crc32(state.chunk_crc, rec),
        chunk_size: state.chunk_size + size,
        chunk_start: min(state.chunk_start || log_time, log_time),
        chunk_end: max(state.chunk_end || log_time, log_time),
        chunk_index: index,
        sequence: Map.put(state.sequence, channel_id, seq + 1),
        counts: Map.update(state.counts, channel_id, 1, &(&1 + 1)),
        start_time: min(state.start_time || log_time, log_time),
        end_time: max(state.end_time || log_time, log_time)
    }

    if state.chunk_size >= state.chunk_bytes, do: flush(state), else: {state, []}
  end

  # the chunk being filled, with its message indexes; its chunk index kept for the summary
  defp flush(%__MODULE__{chunk_size: 0} = state), do: {state, []}

  defp flush(state) do
    chunk_at = state.offset

    chunk =
      record(0x06, [
        <<state.chunk_start::little-64, state.chunk_end::little-64, state.chunk_size::little-64,
          state.chunk_crc::little-32>>,
        str(""),
        <<state.chunk_size::little-64>>,
        state.chunk
      ])

    chunk_length = IO.iodata_length(chunk)
    {state, out} = emit(state, chunk)

    {state, indexes, offsets} =
      state.chunk_index
      |> Enum.sort()
      |> Enum.reduce({state, [], []}, fn {ch, entries}, {state, acc, offsets} ->
        pairs =
          entries |> Enum.reverse() |> Enum.map(fn {t, o} -> <<t::little-64, o::little-64>> end)

        rec = record(0x07, [<<ch::little-16>>, array(pairs)])
        at = state.offset
        {state, bytes} = emit(state, rec)
        {state, [acc, bytes], [<<ch::little-16, at::little-64>> | offsets]}
      end)

    index_length = state.offset - chunk_at - chunk_length

    chunk_index =
      record(0x08, [
        <<state.chunk_start::little-64, state.chunk_end::little-64, chunk_at::little-64,
          chunk_length::little-64>>,
        array(Enum.reverse(offsets)),
        <<index_length::little-64>>,
        str(""),
        <<state.chunk_size::little-64, state.chunk_size::little-64>>
      ])

    state = %{
      state
      | chunk: [],
        chunk_size: 0,
        chunk_crc: 0,
        chunk_start: nil,
        chunk_end: nil,
        chunk_index: %{},
        chunk_indexes: [chunk_index | state.chunk_indexes]
    }

    {state, [out, indexes]}
  end

  @doc "Ends the file: the last chunk, Data End, the summary, its offsets, the footer, magic."
  @spec finish(t()) :: iodata()
  def finish(state) do
    {state, last} = flush(state)
    {state, data_end} = emit(state, record(0x0F, <<state.crc::little-32>>))
    summary_start = state.offset

    counts =
      state.counts |> Enum.sort() |> Enum.map(fn {ch, n} -> <<ch::little-16, n::little-64>> end)

    start_time = state.start_time || 0
    end_time = state.end_time || 0

    statistics =
      record(0x0B, [
        <<Enum.sum(Map.values(state.counts))::little-64, length(state.schemas)::little-16,
          length(state.channels)::little-32, 0::little-32, length(state.metadata)::little-32,
          length(state.chunk_indexes)::little-32, start_time::little-64, end_time::little-64>>,
        array(counts)
      ])

    metadata_indexes =
      state.metadata
      |> Enum.reverse()
      |> Enum.map(fn {at, len, name} ->
        record(0x0D, [<<at::little-64, len::little-64>>, str(name)])
      end)

    groups = [
      {0x03, Enum.map(state.schemas, &schema/1)},
      {0x04, Enum.map(state.channels, &channel/1)},
      {0x0B, [statistics]},
      {0x0D, metadata_indexes},
      {0x08, Enum.reverse(state.chunk_indexes)}
    ]

    {summary, offsets, _at} =
      Enum.reduce(groups, {[], [], summary_start}, fn
        {_op, []}, acc ->
          acc

        {op, records}, {summary, offsets, at} ->
          len = IO.iodata_length(records)
          offset = record(0x0E, <<op, at::little-64, len::little-64>>)
          {[summary, records], [offsets, offset], at + len}
      end)

    summary_offset_start = summary_start + IO.iodata_length(summary)

    footer_head =
      <<0x02, 20::little-64, summary_start::little-64, summary_offset_start::little-64>>

    summary_crc = :erlang.crc32([summary, offsets, footer_head])

    [last, data_end, summary, offsets, footer_head, <<summary_crc::little-32>>, @magic]
  end

  # bytes out: the offset and the data section's CRC go on
  defp emit(state, iodata),
    do:
      {%{
         state
         | offset: state.offset + IO.iodata_length(iodata),
           crc: :erlang.crc32(state.crc, iodata)
       }, iodata}

  defp schema(s),
    do:
      record(0x03, [
        <<s.id::little-16>>,
        str(s.name),
        str(s.encoding),
        <<byte_size(s.data)::little-32>>,
        s.data
      ])

  defp channel(c),
    do:
      record(0x04, [
        <<c.id::little-16, c.schema_id::little-16>>,
        str(c.topic),
        str(c.message_encoding),
        string_map(Map.get(c, :metadata, %{}))
      ])

  defp record(op, content), do: [<<op, IO.iodata_length(content)::little-64>>, content]
  defp str(text), do: [<<byte_size(text)::little-32>>, text]
  defp array(items), do: [<<IO.iodata_length(items)::little-32>>, items]

  defp string_map(map),
    do:
      map
      |> Enum.sort()
      |> Enum.map(fn {k, v} -> [str(to_string(k)), str(to_string(v))] end)
      |> array()
end
