# Fuzz run of the MAVLink decoder (Neptunus.Protocol.MAVLink): FRAMES frames (200 000 by
# default) of valid, signed, mutated, cut-short and unknown messages and random garbage, from
# three senders with their own sequence numbers, cut into random chunks of 1..512 bytes (as a
# UDP socket or a serial line delivers them) and decoded.
#
#   bench/mavlink_fuzz [FRAMES] [SEED]
#
# Prints throughput and counts. It checks invariants while it runs — nothing raises, the
# decoder never holds a frame's worth of bytes or more, decoding in chunks gives exactly what
# decoding in one piece gives, every valid frame not overrun by garbage is decoded as sent —
# and exits 1 if one is violated (a bug, not a slow result). Generation is not timed.

alias Neptunus.Protocol.MAVLink
alias Neptunus.Protocol.MAVLink.{CRC, Messages}

{total, seed} =
  case System.argv() do
    [n, s] -> {String.to_integer(n), String.to_integer(s)}
    [n] -> {String.to_integer(n), 42}
    [] -> {200_000, 42}
  end

:rand.seed(:exsss, {seed, seed * 7 + 1, seed * 13 + 2})

defmodule Fuzz do
  import Bitwise, only: [<<<: 2, bxor: 2]

  @definitions Messages.all()
  @senders [{1, 1}, {1, 2}, {255, 190}]
  # message ids a vehicle sends that have no definition here (AHRS2, RAW_IMU, MEMINFO, …)
  @unknown_ids [27, 42, 125, 152, 163, 178, 193, 241, 11_030]

  def senders, do: @senders

  # One frame: {kind, bytes, sent message or nil}; `seqs` is each sender's next sequence.
  def frame(seqs) do
    case :rand.uniform(100) do
      n when n <= 50 -> valid(seqs, :valid)
      n when n <= 55 -> valid(seqs, :signed)
      n when n <= 70 -> damaged(seqs, :mutated)
      n when n <= 75 -> damaged(seqs, :cut)
      n when n <= 85 -> unknown(seqs)
      _ -> {{:garbage, :rand.bytes(:rand.uniform(100)), nil}, seqs}
    end
  end

  defp next(seqs) do
    sender = Enum.random(@senders)
    seq = Map.fetch!(seqs, sender)
    {sender, seq, Map.put(seqs, sender, MAVLink.next_seq(seq))}
  end

  defp valid(seqs, kind) do
    {{system, component}, seq, seqs} = next(seqs)
    definition = Enum.random(@definitions)
    fields = Map.new(definition.fields, &{&1.name, value(&1)})
    # MAVLink 1 carries one-byte message ids only (CONTROL_STATUS, 512, is MAVLink 2 alone)
    version = if kind == :valid and definition.id < 256 and :rand.uniform(5) == 1, do: 1, else: 2
    header = %{system: system, component: component, seq: seq}
    {:ok, frame} = MAVLink.encode(definition.name, fields, header, version)
    frame = if kind == :signed, do: sign(frame), else: frame

    expected = {definition.name, system, component, seq, received(definition, fields, version)}

    {{kind, frame, expected}, seqs}
  end

  defp damaged(seqs, kind) do
    {{_, frame, _}, seqs} = valid(seqs, :valid)

    frame =
      case kind do
        :cut -> binary_part(frame, 0, :rand.uniform(byte_size(frame) - 1))
        :mutated -> Enum.reduce(1..:rand.uniform(3), frame, fn _, f -> mutate(f) end)
      end

    {{kind, frame, nil}, seqs}
  end

  defp unknown(seqs) do
    {{system, component}, seq, seqs} = next(seqs)
    payload = :rand.bytes(:rand.uniform(60))
    id = Enum.random(@unknown_ids)

    frame =
      <<0xFD, byte_size(payload), 0, 0, seq, system, component, id::little-24, payload::binary,
        :rand.uniform(65_535)::16>>

    {{:unknown, frame, nil}, seqs}
  end

  defp mutate(frame) do
    at = :rand.uniform(byte_size(frame)) - 1
    <<head::binary-size(at), byte, tail::binary>> = frame

    case :rand.uniform(3) do
      1 -> <<head::binary, bxor(byte, :rand.uniform(255)), tail::binary>>
      2 -> head <> tail
      3 -> <<head::binary, :rand.uniform(256) - 1, byte, tail::binary>>
    end
  end

  defp sign(<<0xFD, length, 0, rest::binary>>) do
    <<compat, header::binary-size(6), payload::binary-size(length), _crc::16>> = rest
    checked = <<length, 1, compat, header::binary, payload::binary>>
    <<_::binary-size(6), id::little-24, _::binary>> = checked
    crc = CRC.x25(<<Messages.get(id).crc_extra>>, CRC.x25(checked))
    <<0xFD, checked::binary, crc::little-16, :rand.uniform(256) - 1, :rand.bytes(12)::binary>>
  end

  defp value(%{type: :char, length: n}),
    do: for(_ <- 1..:rand.uniform(n), into: <<>>, do: <<:rand.uniform(255)>>)

  defp value(%{type: type, length: nil}), do: scalar(type)
  defp value(%{type: type, length: n}), do: for(_ <- 1..n, do: scalar(type))

  defp scalar(:uint8), do: :rand.uniform(256) - 1
  defp scalar(:int8), do: :rand.uniform(256) - 129
  defp scalar(:uint16), do: :rand.uniform(65_536) - 1
  defp scalar(:int16), do: :rand.uniform(65_536) - 32_769
  defp scalar(:uint32), do: :rand.uniform(1 <<< 32) - 1
  defp scalar(:int32), do: :rand.uniform(1 <<< 32) - (1 <<< 31) - 1
  defp scalar(:uint64), do: :rand.uniform(1 <<< 64) - 1
  defp scalar(:int64), do: :rand.uniform(1 <<< 64) - (1 <<< 63) - 1

  defp scalar(:float) do
    <<v::float-32>> = <<(:rand.uniform() - 0.5) * 2.0e4::float-32>>
    v
  end

  defp scalar(:double), do: (:rand.uniform() - 0.5) * 1.0e10

  defp received(definition, fields, 2),
    do: Map.new(definition.fields, &{&1.name, fields[&1.name]})

  defp received(definition, fields, 1) do
    Map.new(definition.fields, fn field ->
      {field.name, if(field.extension, do: zero(field), else: fields[field.name])}
    end)
  end

  defp zero(%{type: :char}), do: ""
  defp zero(%{type: t, length: nil}) when t in [:float, :double], do: 0.0
  defp zero(%{length: nil}), do: 0
  defp zero(%{length: n} = f), do: List.duplicate(zero(%{f | length: nil}), n)

  def chunks(stream, acc \\ [])
  def chunks("", acc), do: Enum.reverse(acc)

  def chunks(stream, acc) do
    n = min(:rand.uniform(512), byte_size(stream))
    <<chunk::binary-size(n), rest::binary>> = stream
    chunks(rest, [chunk | acc])
  end

  def key(message),
    do: {message.name, message.system, message.component, message.seq, message.fields}

  # how many of the sent messages appear, in order, among the decoded ones
  def matched(sent, decoded, count \\ 0)
  def matched([], _decoded, count), do: count
  def matched(_sent, [], count), do: count
  def matched([same | sent], [same | decoded], count), do: matched(sent, decoded, count + 1)

  def matched([s | sent], decoded, count) do
    case Enum.find_index(Enum.take(decoded, 4), &(&1 == s)) do
      nil -> matched(sent, decoded, count)
      i -> matched(sent, Enum.drop(decoded, i + 1), count + 1)
    end
  end
end

seqs = Map.new(Fuzz.senders(), &{&1, 0})

{generated, _} = Enum.map_reduce(1..total, seqs, fn _, seqs -> Fuzz.frame(seqs) end)
stream = generated |> Enum.map(&elem(&1, 1)) |> IO.iodata_to_binary()
chunks = Fuzz.chunks(stream)
kinds = Enum.frequencies_by(generated, &elem(&1, 0))
sent = for {_kind, _frame, expected} <- generated, expected != nil, do: expected

IO.puts("# MAVLink fuzz: #{total} frames, seed #{seed}, #{byte_size(stream)} bytes")

violations = :counters.new(1, [])

violation = fn text ->
  IO.puts("INVARIANT VIOLATED: " <> text)
  :counters.add(violations, 1, 1)
end

{us, {decoder, decoded, max_buffer}} =
  :timer.tc(fn ->
    Enum.reduce(chunks, {MAVLink.new(), [], 0}, fn chunk, {decoder, acc, max_buffer} ->
      {decoder, messages, _events} = MAVLink.decode(decoder, chunk)
      {decoder, [messages | acc], max(max_buffer, byte_size(decoder.buffer))}
    end)
  end)

decoded = decoded |> Enum.reverse() |> List.flatten()

if max_buffer > 280, do: violation.("the decoder held #{max_buffer} bytes")

{whole, whole_messages, _} = MAVLink.decode(MAVLink.new(), stream)

unless whole_messages == decoded and MAVLink.stats(whole) == MAVLink.stats(decoder),
  do: violation.("decoding in chunks differs from decoding in one piece")

matched = Fuzz.matched(sent, Enum.map(decoded, &Fuzz.key/1))
stats = MAVLink.stats(decoder)

# a valid frame is lost only when garbage before it looked like the start of an unknown
# message's frame and was skipped by that frame's length; never more than a handful
if length(sent) - matched > div(total, 100),
  do: violation.("#{length(sent) - matched} of #{length(sent)} valid frames not decoded as sent")

out = fn label, value -> IO.puts(String.pad_trailing(label <> ":", 44) <> to_string(value)) end
seconds = us / 1_000_000

out.("generated by kind", inspect(Enum.sort(kinds)))

out.(
  "bytes fed (random chunks of 1..512)",
  "#{byte_size(stream)} (#{Float.round(byte_size(stream) / 1_048_576, 1)} MiB)"
)

out.("decode time", "#{Float.round(seconds, 2)} s")

out.(
  "throughput",
  "#{round(total / seconds)} frames/s, #{Float.round(byte_size(stream) / 1_048_576 / seconds, 1)} MiB/s"
)

# for comparison: a clean stream (only the valid and signed frames, same chunk sizes), and the
# encoder on the same messages
clean = for {kind, frame, _} <- generated, kind in [:valid, :signed], into: <<>>, do: frame
clean_chunks = Fuzz.chunks(clean)

{clean_us, _} =
  :timer.tc(fn ->
    Enum.reduce(clean_chunks, MAVLink.new(), fn chunk, d -> elem(MAVLink.decode(d, chunk), 0) end)
  end)

to_encode =
  for {name, system, component, seq, fields} <- sent,
      do: {name, fields, %{system: system, component: component, seq: seq}}

{encode_us, _} =
  :timer.tc(fn ->
    Enum.each(to_encode, fn {name, fields, header} ->
      {:ok, _} = MAVLink.encode(name, fields, header)
    end)
  end)

out.(
  "clean stream: decode",
  "#{round(length(sent) / (clean_us / 1_000_000))} frames/s, #{Float.round(byte_size(clean) / 1_048_576 / (clean_us / 1_000_000), 1)} MiB/s"
)

out.("encode (MAVLink 2)", "#{round(length(sent) / (encode_us / 1_000_000))} frames/s")
out.("messages decoded", stats.messages)
out.("valid frames decoded as sent / sent", "#{matched} / #{length(sent)}")
out.("decoded from damaged frames (still valid)", length(decoded) - matched)

out.(
  "dropped: garbage bytes / bad checksums / unknown",
  "#{stats.garbage_bytes} / #{stats.bad_checksum} / #{stats.unknown}"
)

out.("senders seen (3 real, the rest made up by damage)", map_size(MAVLink.sources(decoder)))

real_lost =
  MAVLink.sources(decoder)
  |> Map.take(Fuzz.senders())
  |> Enum.map(fn {_, s} -> s.lost end)
  |> Enum.sum()

out.("lost (sequence gaps): all senders / the 3 real", "#{stats.lost} / #{real_lost}")
out.("largest buffer held", "#{max_buffer} bytes")
out.("invariant violations", :counters.get(violations, 1))

if :counters.get(violations, 1) > 0, do: System.halt(1)
