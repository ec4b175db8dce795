defmodule Neptunus.Vehicle.Board.Readings do
  @moduledoc """
  From the bytes a board sends to board samples: line framing (`Neptunus.Protocol.Lines`),
  parsing and wild-point rejection (`Neptunus.Protocol.OpenROV`), the latest value of every
  field, and counters. Pure; `Neptunus.Vehicle.Board.UART` feeds it.

  An OpenROV board reports its fields on several lines at different rates (navigation data
  `hdgd deap pitc roll yaw fthr` often, `vout iout time pres temp` less often), so a sample
  combines the latest accepted value of each field. A sample is produced for every line that
  brings at least one of the six measurements (`depth heading roll pitch voltage current`),
  once all six have been received since the last `reset/1` (a reopened link starts afresh, so
  a sample never mixes values from before a hangup). Other known fields go to the sample's
  `board` map (e.g. `yaw`, `temperature`, `pressure`, `board_time`, `forward_thrust`);
  unknown keys are kept in `raw` (at most #{64} keys, the latest value of each), not in samples.

  Counters: `lines`, `samples`, `overlong` (lines over the length cap), `malformed`, and the
  wild points by reason `out_of_range`, `not_a_number`, `key_as_value` (see `OpenROV`).
  """

  alias Neptunus.Protocol.{Lines, OpenROV}

  @measurements [:depth, :heading, :roll, :pitch, :voltage, :current]
  @max_raw_keys 64

  @enforce_keys [:lines]
  defstruct [
    :lines,
    measurement: %{},
    board: %{},
    raw: %{},
    counters: %{
      lines: 0,
      samples: 0,
      overlong: 0,
      malformed: 0,
      out_of_range: 0,
      not_a_number: 0,
      key_as_value: 0
    }
  ]

  @typedoc """
  * `lines` — the framer (partial line in progress)
  * `measurement` — latest accepted value of each of the six measurements
  * `board` — latest accepted value of the other known fields
  * `raw` — latest raw value of unknown keys
  * `counters` — see the moduledoc
  """
  @type t :: %__MODULE__{
          lines: Lines.t(),
          measurement: map(),
          board: map(),
          raw: %{String.t() => String.t()},
          counters: %{atom() => non_neg_integer()}
        }

  @doc "Readings with lines capped at `max_line` bytes."
  @spec new(pos_integer()) :: t()
  def new(max_line \\ 512), do: %__MODULE__{lines: Lines.new(max_line)}

  @doc "Forgets the partial line and the latest values (counters are kept): a new link session."
  @spec reset(t()) :: t()
  def reset(%__MODULE__{} = r),
    do: %{r | lines: Lines.new(r.lines.max), measurement: %{}, board: %{}}

  @doc "Feeds bytes read at vehicle time `t` (s); returns the samples they complete, in order."
  @spec feed(t(), binary(), float()) :: {t(), [Neptunus.Vehicle.Board.sample()]}
  def feed(%__MODULE__{} = r, bytes, t) do
    overlong_before = r.lines.overlong
    {lines, framer} = Lines.feed(r.lines, bytes)
    r = %{r | lines: framer} |> bump(:overlong, framer.overlong - overlong_before)

    {r, samples} = Enum.reduce(lines, {r, []}, &line(&1, &2, t))
    {r, Enum.reverse(samples)}
  end

  defp line(text, {r, samples}, t) do
    {fields, rejects} = OpenROV.parse_line(text)

    counters =
      Enum.reduce(rejects, %{r.counters | lines: r.counters.lines + 1}, fn {reason, _, _}, c ->
        Map.update!(c, reason, &(&1 + 1))
      end)

    {measurement, board, raw, measured?} =
      Enum.reduce(fields, {r.measurement, r.board, r.raw, false}, fn
        {key, value}, {m, b, raw, _} when key in @measurements ->
          {Map.put(m, key, value), b, raw, true}

        {key, value}, {m, b, raw, measured?} when is_atom(key) ->
          {m, Map.put(b, key, value), raw, measured?}

        {key, value}, {m, b, raw, measured?} ->
          {m, b, keep_raw(raw, key, value), measured?}
      end)

    r = %{r | counters: counters, measurement: measurement, board: board, raw: raw}

    if measured? and map_size(measurement) == length(@measurements) do
      sample = %{t: t, measurement: measurement, sim: nil, board: board}
      {bump(r, :samples, 1), [sample | samples]}
    else
      {r, samples}
    end
  end

  defp keep_raw(raw, key, value) when map_size(raw) < @max_raw_keys or is_map_key(raw, key),
    do: Map.put(raw, key, value)

  defp keep_raw(raw, _key, _value), do: raw

  defp bump(r, _key, 0), do: r
  defp bump(r, key, n), do: %{r | counters: Map.update!(r.counters, key, &(&1 + n))}

  @doc "Wild points so far (all reasons but malformed)."
  @spec wild_points(t()) :: non_neg_integer()
  def wild_points(%__MODULE__{counters: c}), do: c.out_of_range + c.not_a_number + c.key_as_value
end
