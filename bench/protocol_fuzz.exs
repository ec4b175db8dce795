# Fuzz run of the board-telemetry pipeline: 10⁶ lines (by default) of valid, mutated, wild,
# random and overlong telemetry, cut into random chunks and fed through
# Neptunus.Vehicle.Board.OpenROV.Readings (line framing + Neptunus.Vehicle.Board.OpenROV.Protocol
# parsing + wild-point rejection + sample assembly), exactly as Board.OpenROV.UART does with what
# the serial line delivers.
#
#   bench/protocol_fuzz [LINES] [SEED]
#
# Prints throughput and counts. It checks invariants while it runs — nothing raises, no value
# outside its physical range ever reaches a sample, every line is accounted for — and exits 1
# if one is violated (that is a bug, not a slow result). Generation is not timed.

alias Neptunus.Vehicle.Board.OpenROV
alias Neptunus.Vehicle.Board.OpenROV.Readings

{total, seed} =
  case System.argv() do
    [n, s] -> {String.to_integer(n), String.to_integer(s)}
    [n] -> {String.to_integer(n), 42}
    [] -> {1_000_000, 42}
  end

:rand.seed(:exsss, {seed, seed * 7 + 1, seed * 13 + 2})

defmodule Fuzz do
  @known OpenROV.Protocol.known()
  @keys Map.keys(@known)
  @max_line 512

  def max_line, do: @max_line

  # One line (no newline) and its kind.
  def line do
    case :rand.uniform(100) do
      n when n <= 40 -> {:valid, valid()}
      n when n <= 60 -> {:mutated, mutate(valid(), :rand.uniform(4))}
      n when n <= 75 -> {:wild, wild()}
      n when n <= 90 -> {:random, random_bytes(:rand.uniform(120))}
      n when n <= 95 -> {:overlong, random_bytes(@max_line + :rand.uniform(1500))}
      _ -> {:utf8, utf8(:rand.uniform(60))}
    end
  end

  defp valid do
    fields =
      for _ <- 1..:rand.uniform(8) do
        key = Enum.random(@keys)
        {_field, min, max, _} = @known[key]
        value = min + :rand.uniform() * (max - min)
        "#{key}:#{:erlang.float_to_binary(value * 1.0, decimals: :rand.uniform(4) - 1)};"
      end

    unknown = if :rand.uniform(4) == 1, do: ["fmem:#{:rand.uniform(4096)};"], else: []
    IO.iodata_to_binary(fields ++ unknown)
  end

  # the thesis' buffer errors: a decade off, a key in a value's place, lost or extra bytes
  defp mutate(line, 0), do: line

  defp mutate(line, n) do
    line =
      case :rand.uniform(5) do
        1 -> String.replace(line, ".", "0.", global: false)
        2 -> String.replace(line, ~r/:[^;]*/, ":" <> Enum.random(@keys), global: false)
        3 -> delete_byte(line)
        4 -> insert_byte(line, Enum.random([?;, ?:, ?., ?-, ?\r, ?0, :rand.uniform(255)]))
        5 -> binary_part(line, 0, div(byte_size(line), 2))
      end

    mutate(line, n - 1)
  end

  defp wild do
    key = Enum.random(@keys)
    {_field, min, max, _} = @known[key]

    value =
      if :rand.uniform(2) == 1,
        do: max + 1 + :rand.uniform() * 1000,
        else: min - 1 - :rand.uniform() * 1000

    "#{key}:#{:erlang.float_to_binary(value, decimals: 2)};" <> valid()
  end

  defp delete_byte(""), do: ""

  defp delete_byte(line) do
    p = :rand.uniform(byte_size(line)) - 1
    binary_part(line, 0, p) <> binary_part(line, p + 1, byte_size(line) - p - 1)
  end

  defp insert_byte(line, ?\n), do: line

  defp insert_byte(line, byte) do
    p = :rand.uniform(byte_size(line) + 1) - 1
    binary_part(line, 0, p) <> <<byte>> <> binary_part(line, p, byte_size(line) - p)
  end

  defp random_bytes(n), do: :rand.bytes(n) |> :binary.replace("\n", " ", [:global])

  defp utf8(n) do
    for _ <- 1..n, into: "" do
      cp = Enum.random([:rand.uniform(0x7E - 0x20) + 0x1F, :rand.uniform(0xD7FF - 0xA0) + 0xA0])
      <<cp::utf8>>
    end
  end

  def chunks(stream, acc \\ [])
  def chunks("", acc), do: Enum.reverse(acc)

  def chunks(stream, acc) do
    n = min(:rand.uniform(256), byte_size(stream))
    chunks(binary_part(stream, n, byte_size(stream) - n), [binary_part(stream, 0, n) | acc])
  end

  def check_sample!(%{measurement: m, board: board}) do
    for {field, value} <- Map.merge(m, board) do
      # the controller board's own supply current comes from iout, the field :current parses
      {min, max} =
        OpenROV.Protocol.si_range(if field == :board_current, do: :current, else: field)

      unless is_float(value) and value >= min and value <= max do
        raise "out-of-range value reached a sample: #{field} = #{inspect(value)}"
      end
    end
  end
end

batch = 100_000
batches = div(total + batch - 1, batch)

IO.puts("# protocol fuzz: #{total} lines, seed #{seed}, line cap #{Fuzz.max_line()} bytes")

{readings, stats} =
  Enum.reduce(
    1..batches,
    {Readings.new(Fuzz.max_line()),
     %{kinds: %{}, us: 0, parse_us: 0, bytes: 0, samples: 0, lines: []}},
    fn b, {readings, stats} ->
      n = min(batch, total - (b - 1) * batch)
      generated = for _ <- 1..n, do: Fuzz.line()

      kinds =
        Enum.reduce(generated, stats.kinds, fn {kind, _}, acc ->
          Map.update(acc, kind, 1, &(&1 + 1))
        end)

      stream =
        IO.iodata_to_binary(
          Enum.map(generated, fn {_kind, line} ->
            [line, if(:rand.uniform(2) == 1, do: "\r\n", else: "\n")]
          end)
        )

      chunks = Fuzz.chunks(stream)

      # framing + parsing + samples, as Board.OpenROV.UART runs it
      {us, {readings, samples}} =
        :timer.tc(fn ->
          Enum.reduce(chunks, {readings, []}, fn chunk, {r, acc} ->
            {r, samples} = Readings.feed(r, chunk, 0.0)
            {r, [samples | acc]}
          end)
        end)

      # the invariant, checked outside the timing
      samples = samples |> List.flatten() |> Enum.map(&Fuzz.check_sample!/1) |> length()

      # the parser alone, on the same lines
      lines = for {kind, line} <- generated, kind != :overlong, do: line
      {parse_us, _} = :timer.tc(fn -> Enum.each(lines, &OpenROV.Protocol.parse_line/1) end)

      {readings,
       %{
         stats
         | kinds: kinds,
           us: stats.us + us,
           parse_us: stats.parse_us + parse_us,
           bytes: stats.bytes + byte_size(stream),
           samples: stats.samples + samples
       }}
    end
  )

c = readings.counters
expected_lines = total - Map.get(stats.kinds, :overlong, 0)
out = fn label, value -> IO.puts(String.pad_trailing(label <> ":", 40) <> to_string(value)) end
rate = fn count, us -> "#{round(count / (us / 1_000_000))}/s" end

out.("generated by kind", inspect(Enum.sort(stats.kinds)))

out.(
  "bytes fed (random chunks of 1..256)",
  "#{stats.bytes} (#{Float.round(stats.bytes / 1_048_576, 1)} MiB)"
)

out.("pipeline time (framing+parse+samples)", "#{Float.round(stats.us / 1_000_000, 2)} s")

out.(
  "pipeline throughput",
  "#{rate.(total, stats.us)} lines, #{Float.round(stats.bytes / 1_048_576 / (stats.us / 1_000_000), 1)} MiB/s"
)

out.("parse_line alone", "#{rate.(expected_lines, stats.parse_us)} lines")
out.("lines framed / expected", "#{c.lines} / #{expected_lines}")
out.("overlong dropped / generated", "#{c.overlong} / #{Map.get(stats.kinds, :overlong, 0)}")
out.("samples (all values in range)", stats.samples)
out.("plain-text lines (known shapes)", c.text)
out.("debug fields (log)", c.debug)
out.("boot placeholder depths", c.placeholder)
out.("rejects: malformed", c.malformed)
out.("wild points: out_of_range", c.out_of_range)
out.("wild points: not_a_number", c.not_a_number)
out.("wild points: key_as_value", c.key_as_value)

if c.lines != expected_lines or c.overlong != Map.get(stats.kinds, :overlong, 0) do
  IO.puts("INVARIANT VIOLATED: framing lost or invented lines")
  System.halt(1)
end

out.("invariant violations", 0)
