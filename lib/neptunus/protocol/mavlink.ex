defmodule Neptunus.Protocol.MAVLink do
  @moduledoc """
  MAVLink codec: frames to messages and messages to frames. Pure: no processes, no I/O; input
  from the link never raises.

  ## What it implements

    * **MAVLink 2 frames** (start byte 0xFD): a 10-byte header (payload length, incompatibility
      and compatibility flags, sequence, system id, component id, 24-bit message id), the
      payload, the 16-bit checksum and, when the incompatibility flag 0x01 is set, a 13-byte
      signature (link id, 48-bit timestamp, 48-bit signature), which is parsed and exposed in
      `Message.signature` with the bytes it covers; `Neptunus.Protocol.MAVLink.Signing`
      verifies and makes signatures. Frames with any other incompatibility flag
      cannot be understood and are dropped like garbage, as the spec requires.
    * **MAVLink 1 frames** (start byte 0xFE) on input: a 6-byte header with an 8-bit message id.
      `encode/4` writes them too (version 1) for messages with an id below 256.
    * The **checksum**: CRC-16/MCRF4XX ("X.25", `Neptunus.Protocol.MAVLink.CRC`) over the frame
      after the start byte up to the end of the payload, then the message's CRC_EXTRA byte.
    * **Payload truncation**: a MAVLink 2 frame is sent without the payload's trailing zero
      bytes (at least one byte stays); a shorter payload is zero-extended on receive, a longer
      one (a sender with a newer definition: more extension fields) is read up to what we know.
    * **Sequence numbers**: the caller keeps one per sender and passes it in the header
      (`next_seq/1` steps it). On receive, each sender `{system, component}` is tracked and the
      gap to its last sequence number counted as lost frames: `(seq - last - 1) mod 256`, as
      pymavlink counts it (so a repeated frame counts as 255 lost). Frames of unknown messages
      count as received: a vehicle sends many messages we have no definition for.
    * The messages of `Neptunus.Protocol.MAVLink.Messages`, their wire order and CRC_EXTRA
      computed from their XML declarations.

  Not implemented: messages beyond those defined (other
  `common.xml` messages and dialects such as `ardupilotmega.xml` are skipped as unknown until
  their declarations are added to `Messages`).

  ## Decoding

  `decode(decoder, bytes)` takes what the link delivered (any chunking) and returns
  `{decoder, messages, events}`: the `Neptunus.Protocol.MAVLink.Message`s completed, in order,
  and what was dropped, in order:

    * `{:garbage, bytes}` — bytes skipped while looking for a frame start (two garbage events
      next to each other in the list are merged into one);
    * `{:bad_checksum, message_id}` — a known message whose checksum does not match: its start
      byte is dropped (counted as garbage too) and the search goes on from the next byte, so
      a frame hidden in a corrupt one is still found;
    * `{:unknown_message, message_id, {system, component}}` — no definition: skipped by its
      length. Its checksum cannot be checked without a CRC_EXTRA, so the frame is taken only
      if another frame starts right after it (one more byte is awaited when it ends a chunk);
      otherwise its start byte is dropped as garbage and the search goes on, so that garbage
      which looks like a frame header does not swallow the frames that follow it;
    * `{:lost, {system, component}, frames}` — a gap in a sender's sequence numbers.

  An incomplete frame at the end is kept for the next chunk (and a complete frame of an
  unknown message until the next byte arrives); that is at most the longest frame (280 bytes),
  so the decoder's memory stays bounded. The counters are in
  `stats/1` and `sources/1` (`Neptunus.Protocol.MAVLink.Decoder`).

  ## Encoding

  `encode(message, fields, %{system: 255, component: 190, seq: n}, version)` with the
  message's name (`:heartbeat`) or id and its fields as a map. Every field that is not an
  extension must be given (HEARTBEAT's `mavlink_version` defaults to 3); extension fields
  default to zero. Values must fit their type: integers in range; floats as numbers within
  the type's range or `:nan` / `:infinity` / `:neg_infinity`; `char[N]` as a binary of at most
  N bytes without NUL; other arrays as lists of exactly N values. Anything else is
  `{:error, reason}`, with nothing encoded.
  """

  import Bitwise

  alias Neptunus.Protocol.MAVLink.{CRC, Decoder, Message, Messages}

  @v2 0xFD
  @v1 0xFE
  @signed 0x01
  @signature_length 13

  @typedoc "Where a frame comes from: our system and component ids and this sender's sequence."
  @type header :: %{system: byte(), component: byte(), seq: byte()}
  @type event ::
          {:garbage, pos_integer()}
          | {:bad_checksum, non_neg_integer()}
          | {:unknown_message, non_neg_integer(), Decoder.source()}
          | {:lost, Decoder.source(), pos_integer()}
  @type encode_error ::
          {:unknown_message, term()}
          | {:bad_header, term()}
          | {:bad_version, term()}
          | {:not_in_mavlink1, non_neg_integer()}
          | {:bad_fields, term()}
          | {:unknown_field, term()}
          | {:missing_field, atom()}
          | {:bad_value, atom(), term()}

  @doc "A decoder with nothing received yet."
  @spec new() :: Decoder.t()
  def new, do: %Decoder{}

  @doc "The counters of a decoder (see `Neptunus.Protocol.MAVLink.Decoder`)."
  @spec stats(Decoder.t()) :: Decoder.stats()
  def stats(%Decoder{stats: stats}), do: stats

  @doc "Per sender `{system, component}`: frames received and lost, last sequence number."
  @spec sources(Decoder.t()) :: %{
          Decoder.source() => %{
            received: pos_integer(),
            lost: non_neg_integer(),
            last_seq: byte()
          }
        }
  def sources(%Decoder{sources: sources}), do: sources

  @doc "The sequence number after `seq` (wraps at 256)."
  @spec next_seq(byte()) :: byte()
  def next_seq(seq) when is_integer(seq) and seq in 0..255, do: rem(seq + 1, 256)

  # ── decoding ──────────────────────────────────────────────────────────────────────────

  @doc """
  Feeds bytes from the link to the decoder. Returns the new decoder, the messages completed
  and the events (see the module doc). Never raises on any input.
  """
  @spec decode(Decoder.t(), binary()) :: {Decoder.t(), [Message.t()], [event()]}
  def decode(%Decoder{buffer: buffer} = decoder, bytes) when is_binary(bytes) do
    {decoder, messages, events} = scan(buffer <> bytes, %{decoder | buffer: <<>>}, [], [])
    {decoder, Enum.reverse(messages), Enum.reverse(events)}
  end

  defp scan(<<>>, decoder, messages, events), do: {decoder, messages, events}

  defp scan(bytes, decoder, messages, events) do
    case :binary.match(bytes, [<<@v2>>, <<@v1>>]) do
      :nomatch ->
        {decoder, events} = garbage(decoder, events, byte_size(bytes))
        {decoder, messages, events}

      {0, 1} ->
        frame(bytes, decoder, messages, events)

      {at, 1} ->
        {decoder, events} = garbage(decoder, events, at)
        <<_::binary-size(at), rest::binary>> = bytes
        frame(rest, decoder, messages, events)
    end
  end

  # MAVLink 2
  defp frame(
         <<@v2, length, incompat, _compat, seq, system, component, id::little-24, rest::binary>> =
           bytes,
         decoder,
         messages,
         events
       )
       when incompat in [0, @signed] do
    signature_length = if incompat == @signed, do: @signature_length, else: 0

    case rest do
      <<payload::binary-size(length), crc::little-16, signature::binary-size(signature_length),
        after_frame::binary>> ->
        <<_, checked::binary-size(9 + length), _::binary>> = bytes
        # what a signature covers: the frame up to its timestamp (Signing.verify/2)
        signed = binary_part(bytes, 0, 12 + length + max(signature_length - 6, 0))
        signature = parse_signature(signature, signed)
        frame = {2, id, seq, system, component, payload, signature}
        accept(frame, checked, crc, bytes, after_frame, decoder, messages, events)

      _ ->
        {%{decoder | buffer: bytes}, messages, events}
    end
  end

  defp frame(
         <<@v2, _, _incompat, _::binary-size(7), _::binary>> = bytes,
         decoder,
         messages,
         events
       ),
       do: drop_start(bytes, decoder, messages, events)

  # MAVLink 1
  defp frame(
         <<@v1, length, seq, system, component, id, rest::binary>> = bytes,
         decoder,
         messages,
         events
       ) do
    case rest do
      <<payload::binary-size(length), crc::little-16, after_frame::binary>> ->
        <<_, checked::binary-size(5 + length), _::binary>> = bytes
        frame = {1, id, seq, system, component, payload, nil}
        accept(frame, checked, crc, bytes, after_frame, decoder, messages, events)

      _ ->
        {%{decoder | buffer: bytes}, messages, events}
    end
  end

  # a header not complete yet
  defp frame(bytes, decoder, messages, events), do: {%{decoder | buffer: bytes}, messages, events}

  defp accept(frame, checked, crc, bytes, after_frame, decoder, messages, events) do
    {version, id, seq, system, component, payload, signature} = frame

    case Messages.get(id) do
      nil ->
        # without a CRC_EXTRA the checksum proves nothing: the frame is taken only when the
        # next frame starts right after it (garbage seldom passes this and so seldom swallows
        # the frames after it); at the end of the bytes, it waits for the next one
        case after_frame do
          <<>> ->
            {%{decoder | buffer: bytes}, messages, events}

          <<next, _::binary>> when next in [@v2, @v1] ->
            events = [{:unknown_message, id, {system, component}} | events]
            source = {system, component}
            {decoder, events} = count(decoder, :unknown) |> sequence(source, seq, events)
            scan(after_frame, decoder, messages, events)

          _ ->
            drop_start(bytes, decoder, messages, events)
        end

      definition ->
        if CRC.x25(<<definition.crc_extra>>, CRC.x25(checked)) == crc do
          message = %Message{
            id: id,
            name: definition.name,
            system: system,
            component: component,
            seq: seq,
            version: version,
            fields: decode_payload(definition, payload),
            signature: signature
          }

          {decoder, events} =
            count(decoder, :messages) |> sequence({system, component}, seq, events)

          scan(after_frame, decoder, [message | messages], events)
        else
          decoder = count(decoder, :bad_checksum)
          drop_start(bytes, decoder, messages, [{:bad_checksum, id} | events])
        end
    end
  end

  defp drop_start(<<_, rest::binary>>, decoder, messages, events) do
    {decoder, events} = garbage(decoder, events, 1)
    scan(rest, decoder, messages, events)
  end

  defp garbage(decoder, events, 0), do: {decoder, events}

  defp garbage(%Decoder{stats: stats} = decoder, events, n) do
    decoder = %{decoder | stats: %{stats | garbage_bytes: stats.garbage_bytes + n}}

    case events do
      [{:garbage, m} | rest] -> {decoder, [{:garbage, m + n} | rest]}
      _ -> {decoder, [{:garbage, n} | events]}
    end
  end

  defp count(%Decoder{stats: stats} = decoder, key),
    do: %{decoder | stats: Map.update!(stats, key, &(&1 + 1))}

  # Remembers the sender's sequence number; the gap since its last one is the number of the
  # sender's frames that did not arrive (an event when there is one).
  defp sequence(%Decoder{sources: sources, stats: stats} = decoder, source, seq, events) do
    case sources do
      %{^source => %{last_seq: last} = known} ->
        gap = seq - last - 1 &&& 0xFF
        entry = %{known | received: known.received + 1, lost: known.lost + gap, last_seq: seq}

        decoder = %{
          decoder
          | sources: Map.put(sources, source, entry),
            stats: %{stats | lost: stats.lost + gap}
        }

        {decoder, if(gap > 0, do: [{:lost, source, gap} | events], else: events)}

      _ ->
        entry = %{received: 1, lost: 0, last_seq: seq}
        {%{decoder | sources: Map.put(sources, source, entry)}, events}
    end
  end

  defp parse_signature(<<>>, _signed), do: nil

  defp parse_signature(<<link_id, timestamp::little-48, signature::binary-size(6)>>, signed),
    do: %{link_id: link_id, timestamp: timestamp, signature: signature, signed: signed}

  defp decode_payload(definition, payload) do
    payload =
      case definition.full_length - byte_size(payload) do
        missing when missing > 0 -> payload <> <<0::size(missing)-unit(8)>>
        _ -> binary_part(payload, 0, definition.full_length)
      end

    {fields, <<_::binary>>} =
      Enum.reduce(definition.wire, {%{}, payload}, fn field, {fields, bytes} ->
        {value, rest} = read_field(field, bytes)
        {Map.put(fields, field.name, value), rest}
      end)

    fields
  end

  defp read_field(%{type: :char, length: n}, bytes) do
    <<string::binary-size(n), rest::binary>> = bytes
    [text | _] = :binary.split(string, <<0>>)
    {text, rest}
  end

  defp read_field(%{type: type, length: nil}, bytes), do: read_value(type, bytes)

  defp read_field(%{type: type, length: n}, bytes) do
    {values, rest} = Enum.map_reduce(1..n, bytes, fn _, bytes -> read_value(type, bytes) end)

    {values, rest}
  end

  defp read_value(:uint8, <<v, rest::binary>>), do: {v, rest}
  defp read_value(:int8, <<v::signed, rest::binary>>), do: {v, rest}
  defp read_value(:uint16, <<v::little-16, rest::binary>>), do: {v, rest}
  defp read_value(:int16, <<v::little-signed-16, rest::binary>>), do: {v, rest}
  defp read_value(:uint32, <<v::little-32, rest::binary>>), do: {v, rest}
  defp read_value(:int32, <<v::little-signed-32, rest::binary>>), do: {v, rest}
  defp read_value(:uint64, <<v::little-64, rest::binary>>), do: {v, rest}
  defp read_value(:int64, <<v::little-signed-64, rest::binary>>), do: {v, rest}
  defp read_value(:float, <<v::little-float-32, rest::binary>>), do: {v, rest}
  defp read_value(:double, <<v::little-float-64, rest::binary>>), do: {v, rest}

  defp read_value(:float, <<bits::little-32, rest::binary>>),
    do: {special(bits >>> 31, bits &&& 0x7FFFFF), rest}

  defp read_value(:double, <<bits::little-64, rest::binary>>),
    do: {special(bits >>> 63, bits &&& 0xFFFFFFFFFFFFF), rest}

  # a float whose exponent is all ones (Erlang has no such float)
  defp special(_sign, mantissa) when mantissa != 0, do: :nan
  defp special(0, 0), do: :infinity
  defp special(1, 0), do: :neg_infinity

  # ── encoding ──────────────────────────────────────────────────────────────────────────

  @doc """
  Encodes one message into a frame (`version` 2, the default, or 1).

      iex> {:ok, frame} =
      ...>   Neptunus.Protocol.MAVLink.encode(
      ...>     :heartbeat,
      ...>     %{type: 6, autopilot: 8, base_mode: 0, custom_mode: 0, system_status: 4},
      ...>     %{system: 255, component: 190, seq: 0}
      ...>   )
      iex> Base.encode16(frame)
      "FD09000000FFBE0000000000000006080004033D48"
  """
  @spec encode(atom() | non_neg_integer(), map(), header(), 1 | 2) ::
          {:ok, binary()} | {:error, encode_error()}
  def encode(message, fields, header, version \\ 2) do
    with {:ok, definition} <- definition(message),
         :ok <- check_header(header),
         :ok <- check_version(version, definition),
         {:ok, fields} <- check_fields(definition, fields),
         {:ok, payload} <- payload(definition, fields) do
      {:ok, build_frame(version, definition, payload, header)}
    end
  end

  defp definition(message) do
    case Messages.get(message) do
      nil -> {:error, {:unknown_message, message}}
      definition -> {:ok, definition}
    end
  end

  defp check_header(%{system: system, component: component, seq: seq})
       when system in 0..255 and component in 0..255 and seq in 0..255,
       do: :ok

  defp check_header(header), do: {:error, {:bad_header, header}}

  defp check_version(2, _definition), do: :ok
  defp check_version(1, %{id: id}) when id < 256, do: :ok
  defp check_version(1, %{id: id}), do: {:error, {:not_in_mavlink1, id}}
  defp check_version(version, _definition), do: {:error, {:bad_version, version}}

  defp check_fields(definition, fields) when is_map(fields) do
    names = MapSet.new(definition.fields, & &1.name)

    case Enum.find(Map.keys(fields), &(not MapSet.member?(names, &1))) do
      nil ->
        Enum.reduce_while(definition.fields, {:ok, fields}, fn field, {:ok, fields} ->
          case Map.fetch(fields, field.name) do
            {:ok, value} ->
              if valid?(field, value),
                do: {:cont, {:ok, fields}},
                else: {:halt, {:error, {:bad_value, field.name, value}}}

            :error ->
              case default(definition, field) do
                {:ok, value} -> {:cont, {:ok, Map.put(fields, field.name, value)}}
                :none -> {:halt, {:error, {:missing_field, field.name}}}
              end
          end
        end)

      unknown ->
        {:error, {:unknown_field, unknown}}
    end
  end

  defp check_fields(_definition, fields), do: {:error, {:bad_fields, fields}}

  defp default(%{name: :heartbeat}, %{name: :mavlink_version}), do: {:ok, 3}
  defp default(_definition, %{extension: true} = field), do: {:ok, zero(field)}
  defp default(_definition, _field), do: :none

  defp zero(%{type: :char}), do: ""
  defp zero(%{type: type, length: nil}), do: zero_value(type)
  defp zero(%{type: type, length: n}), do: List.duplicate(zero_value(type), n)

  defp zero_value(type) when type in [:float, :double], do: 0.0
  defp zero_value(_type), do: 0

  @float32_max 3.4028234663852886e38

  defp valid?(%{type: :char, length: n}, value),
    do: is_binary(value) and byte_size(value) <= n and not String.contains?(value, <<0>>)

  defp valid?(%{type: type, length: nil}, value), do: valid_value?(type, value)

  defp valid?(%{type: type, length: n}, value),
    do: is_list(value) and length(value) == n and Enum.all?(value, &valid_value?(type, &1))

  defp valid_value?(:uint8, v), do: is_integer(v) and v in 0..0xFF
  defp valid_value?(:int8, v), do: is_integer(v) and v in -0x80..0x7F
  defp valid_value?(:uint16, v), do: is_integer(v) and v in 0..0xFFFF
  defp valid_value?(:int16, v), do: is_integer(v) and v in -0x8000..0x7FFF
  defp valid_value?(:uint32, v), do: is_integer(v) and v in 0..0xFFFFFFFF
  defp valid_value?(:int32, v), do: is_integer(v) and v in -0x80000000..0x7FFFFFFF
  defp valid_value?(:uint64, v), do: is_integer(v) and v in 0..0xFFFFFFFFFFFFFFFF

  defp valid_value?(:int64, v),
    do: is_integer(v) and v in -0x8000000000000000..0x7FFFFFFFFFFFFFFF

  defp valid_value?(_float, v) when v in [:nan, :infinity, :neg_infinity], do: true
  defp valid_value?(:float, v), do: is_number(v) and abs(v) <= @float32_max
  defp valid_value?(:double, v), do: is_number(v)

  defp payload(definition, fields) do
    payload =
      for field <- definition.wire, into: <<>> do
        write_field(field, Map.fetch!(fields, field.name))
      end

    {:ok, payload}
  end

  defp write_field(%{type: :char, length: n}, text),
    do: text <> <<0::size(n - byte_size(text))-unit(8)>>

  defp write_field(%{type: type, length: nil}, value), do: write_value(type, value)

  defp write_field(%{type: type}, values),
    do: for(value <- values, into: <<>>, do: write_value(type, value))

  defp write_value(:uint8, v), do: <<v>>
  defp write_value(:int8, v), do: <<v::signed>>
  defp write_value(:uint16, v), do: <<v::little-16>>
  defp write_value(:int16, v), do: <<v::little-signed-16>>
  defp write_value(:uint32, v), do: <<v::little-32>>
  defp write_value(:int32, v), do: <<v::little-signed-32>>
  defp write_value(:uint64, v), do: <<v::little-64>>
  defp write_value(:int64, v), do: <<v::little-signed-64>>
  defp write_value(:float, :nan), do: <<0x7FC00000::little-32>>
  defp write_value(:float, :infinity), do: <<0x7F800000::little-32>>
  defp write_value(:float, :neg_infinity), do: <<0xFF800000::little-32>>
  defp write_value(:float, v), do: <<v::little-float-32>>
  defp write_value(:double, :nan), do: <<0x7FF8000000000000::little-64>>
  defp write_value(:double, :infinity), do: <<0x7FF0000000000000::little-64>>
  defp write_value(:double, :neg_infinity), do: <<0xFFF0000000000000::little-64>>
  defp write_value(:double, v), do: <<v::little-float-64>>

  defp build_frame(2, definition, payload, %{system: system, component: component, seq: seq}) do
    payload = truncate(payload)

    checked =
      <<byte_size(payload), 0, 0, seq, system, component, definition.id::little-24,
        payload::binary>>

    <<@v2, checked::binary, checksum(checked, definition)::little-16>>
  end

  defp build_frame(1, definition, payload, %{system: system, component: component, seq: seq}) do
    payload = binary_part(payload, 0, definition.base_length)
    checked = <<byte_size(payload), seq, system, component, definition.id, payload::binary>>
    <<@v1, checked::binary, checksum(checked, definition)::little-16>>
  end

  defp checksum(checked, definition), do: CRC.x25(<<definition.crc_extra>>, CRC.x25(checked))

  @doc """
  The unsigned MAVLink 2 `frame` (as `encode/4` makes it) with sequence number `seq` and
  incompatibility flags `incompat` (0, or 0x01 for a frame a signature will follow: see
  `Neptunus.Protocol.MAVLink.Signing.sign/5`), its checksum recomputed. A broadcast is
  encoded once and each receiver's link stamps its own sequence number on it.

      iex> {:ok, frame} = Neptunus.Protocol.MAVLink.encode(:heartbeat,
      ...>   %{type: 12, autopilot: 0, base_mode: 0, custom_mode: 0, system_status: 3},
      ...>   %{system: 1, component: 1, seq: 0})
      iex> {_, [message], []} =
      ...>   Neptunus.Protocol.MAVLink.decode(Neptunus.Protocol.MAVLink.new(),
      ...>     Neptunus.Protocol.MAVLink.restamp(frame, 42))
      iex> message.seq
      42
  """
  @spec restamp(binary(), byte(), 0 | 1) :: binary()
  def restamp(frame, seq, incompat \\ 0)

  def restamp(
        <<@v2, length, 0, compat, _seq, system, component, id::little-24, rest::binary>>,
        seq,
        incompat
      )
      when seq in 0..255 and incompat in [0, @signed] do
    <<payload::binary-size(length), _crc::little-16>> = rest
    checked = <<length, incompat, compat, seq, system, component, id::little-24, payload::binary>>
    <<@v2, checked::binary, checksum(checked, Messages.get(id))::little-16>>
  end

  # MAVLink 2 drops the payload's trailing zero bytes, keeping at least one
  defp truncate(payload) do
    case :binary.bin_to_list(payload) |> Enum.reverse() |> Enum.drop_while(&(&1 == 0)) do
      [] -> binary_part(payload, 0, 1)
      kept -> binary_part(payload, 0, length(kept))
    end
  end
end
