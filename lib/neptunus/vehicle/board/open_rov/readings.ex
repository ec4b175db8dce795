defmodule Neptunus.Vehicle.Board.OpenROV.Readings do
  @moduledoc """
  From the bytes a board sends to board samples: line framing (`Neptunus.Protocol.Lines`),
  parsing and wild-point rejection (`Neptunus.Vehicle.Board.OpenROV.Protocol`), the latest value of
  every field, and counters. Pure; `Neptunus.Vehicle.Board.OpenROV.UART` feeds it.

  An OpenROV board reports its fields on several lines at different rates (navigation data
  `hdgd deap pitc roll yaw fthr` often, `vout iout time pres temp` less often), so a sample
  combines the latest accepted value of each field. A sample is produced for every line that
  brings at least one of the six measurements (`depth heading roll pitch voltage current`),
  once all six have been received since the last `reset/1` (a reopened link starts afresh, so
  a sample never mixes values from before a hangup). Other known fields go to the sample's
  `board` map (e.g. `yaw`, `temperature`, `pressure`, `board_time`, `forward_thrust`);
  unknown keys are parsed (so a line with them is not malformed) and left out.

  What the fields mean differs between boards, so:

    * **current** — the cape's `iout` is the vehicle's current; the 2.5 controller board's
      `iout` is its own supply current (kept as `board.board_current`) and the vehicle's
      current is its two battery currents `BT1I + BT2I` (a sum beyond the current's range is
      a wild point). A board counts as a controller board once it has reported a battery
      current.
    * **depth** — after a board boots, it prints `deap:0.00` (and `pres:0.00`) until its
      pressure sensor's first reading, about a second later. So depth is *not live* from a
      new link session (`reset/1`: a USB Arduino resets on open) and from a board reset the
      link detected (`board_reset/1`) until the board reports a depth other than 0.00 or a
      pressure above 0 (0 mbar is a vacuum: a `pres:0.00` makes depth not live again). While
      not live, a `deap` is a placeholder: the sample's depth is nil (navigation takes it as
      missing), counted `placeholder`. A depth from before is never carried over into a
      sample either: the value nobody measured since the board booted is not a depth.

  Lines the firmware prints besides fields — the depth driver's plain text
  (`OpenROV.Protocol.text_line?/1`) — are counted as `text`, `log` fields as `debug`; neither is
  malformed. The board's replies the link needs (`pong`, the `cmd:`/`icmd:` echoes — a
  `cmd:` echo with the command's name and arguments as printed —, 30.x `crc:` and `rawcmd:`
  lines, the board's millis from `time`, and `boot:1;`, which the firmware prints when its
  setup is done) are collected as events, oldest first, for `take_events/1` (see
  `Neptunus.Vehicle.Board.OpenROV.BoardLink`).

  Counters: `lines`, `samples`, `overlong` (lines over the length cap), `text`, `debug`,
  `placeholder`, `malformed`, and the wild points by reason `out_of_range`, `not_a_number`,
  `key_as_value` (see `OpenROV`).
  """

  alias Neptunus.Protocol.Lines
  alias Neptunus.Vehicle.Board.OpenROV

  @measurements [:depth, :heading, :roll, :pitch, :voltage, :current]
  @direct_measurements @measurements -- [:current]
  @max_events 256

  @enforce_keys [:lines]
  defstruct [
    :lines,
    measurement: %{},
    board: %{},
    events: [],
    depth_live: false,
    counters: %{
      lines: 0,
      samples: 0,
      overlong: 0,
      text: 0,
      debug: 0,
      placeholder: 0,
      malformed: 0,
      out_of_range: 0,
      not_a_number: 0,
      key_as_value: 0
    }
  ]

  @typedoc "See `Neptunus.Vehicle.Board.OpenROV.BoardLink.event/3`."
  @type event ::
          :rawcmd
          | {:crc, :pass | {:fail, byte(), byte()}}
          | {:echo, String.t(), [String.t()] | nil, boolean()}
          | {:echo_prefixed, String.t()}
          | {:icmd, String.t()}
          | {:pong, OpenROV.Protocol.pong()}
          | {:board_time, non_neg_integer()}
          | :boot

  @typedoc """
  * `lines` — the framer (partial line in progress)
  * `measurement` — latest accepted value of each of the six measurements
  * `board` — latest accepted value of the other known fields
  * `events` — what the link needs to know, newest first (`take_events/1`)
  * `depth_live` — the board has measured a depth since it booted (see the moduledoc)
  * `counters` — see the moduledoc
  """
  @type t :: %__MODULE__{
          lines: Lines.t(),
          measurement: map(),
          board: map(),
          events: [event()],
          depth_live: boolean(),
          counters: %{atom() => non_neg_integer()}
        }

  @doc "Readings with lines capped at `max_line` bytes."
  @spec new(pos_integer()) :: t()
  def new(max_line \\ 512), do: %__MODULE__{lines: Lines.new(max_line)}

  @doc "Forgets the partial line and the latest values (counters are kept): a new link session."
  @spec reset(t()) :: t()
  def reset(%__MODULE__{} = r),
    do: %{
      r
      | lines: Lines.new(r.lines.max),
        measurement: %{},
        board: %{},
        events: [],
        depth_live: false
    }

  @doc """
  The board rebooted (the link saw its uptime go backwards) while the link stayed up: its
  depth is a boot placeholder again until it measures one (see the moduledoc). The other
  latest values are kept: the board prints them again within a second.
  """
  @spec board_reset(t()) :: t()
  def board_reset(%__MODULE__{} = r),
    do: %{r | depth_live: false, measurement: Map.put(r.measurement, :depth, nil)}

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
    if OpenROV.Protocol.text_line?(text) do
      {bump(%{r | counters: %{r.counters | lines: r.counters.lines + 1}}, :text, 1), samples}
    else
      fields_line(text, {r, samples}, t)
    end
  end

  defp fields_line(text, {r, samples}, t) do
    {fields, rejects} = OpenROV.Protocol.parse_line(text)

    counters =
      Enum.reduce(rejects, %{r.counters | lines: r.counters.lines + 1}, fn {reason, _, _}, c ->
        Map.update!(c, reason, &(&1 + 1))
      end)

    r = %{r | counters: counters, events: events(fields, r.events)}
    r = if Map.has_key?(fields, "log"), do: bump(r, :debug, 1), else: r
    {fields, r} = fields |> live_depth(r) |> placeholder()

    {measurement, board, measured?} =
      Enum.reduce(fields, {r.measurement, r.board, false}, fn
        {key, value}, {m, b, _} when key in @direct_measurements ->
          {Map.put(m, key, value), b, true}

        {:current, value}, {m, b, measured?} ->
          # the cape's iout is the vehicle's current; the 2.5 controller board's is its own
          # supply current, and its battery currents BT1I/BT2I are the vehicle's
          if Map.has_key?(b, :battery1_current),
            do: {m, Map.put(b, :board_current, value), measured?},
            else: {Map.put(m, :current, value), b, true}

        {key, value}, {m, b, measured?}
        when key in [:battery1_current, :battery2_current] ->
          b = Map.put(b, key, value)

          case battery_current(b) do
            {:ok, current} -> {Map.put(m, :current, current), b, true}
            :out_of_range -> {m, b, measured?}
          end

        {key, value}, {m, b, measured?} when is_atom(key) ->
          {m, Map.put(b, key, value), measured?}

        # an unknown key
        {_key, _value}, acc ->
          acc
      end)

    r = %{r | measurement: measurement, board: board}

    r =
      if (Map.has_key?(fields, :battery1_current) or Map.has_key?(fields, :battery2_current)) and
           battery_current(board) == :out_of_range,
         do: bump(r, :out_of_range, 1),
         else: r

    if measured? and map_size(measurement) == length(@measurements) do
      sample = %{t: t, measurement: measurement, sim: nil, board: board}
      {bump(r, :samples, 1), [sample | samples]}
    else
      {r, samples}
    end
  end

  # The vehicle's current on the 2.5 controller board: both batteries together, a wild point
  # when the sum is beyond what a current can be (OpenROV.Protocol.si_range(:current)).
  defp battery_current(board) do
    current = Map.get(board, :battery1_current, 0.0) + Map.get(board, :battery2_current, 0.0)
    {_min, max} = OpenROV.Protocol.si_range(:current)
    if current <= max, do: {:ok, current}, else: :out_of_range
  end

  # Depth is live once the board has measured since it booted: a depth other than 0.00 or a
  # pressure above 0; a pres:0.00 says its sensor has not been read (0 mbar is a vacuum).
  defp live_depth(fields, r) do
    live =
      case fields do
        %{pressure: p} when p == 0.0 -> false
        %{pressure: p} when p > 0.0 -> true
        %{depth: d} when d != 0.0 -> true
        _ -> r.depth_live
      end

    {fields, %{r | depth_live: live}}
  end

  # Not live: the deap is the boot placeholder; the sample carries no depth (nil), never an
  # earlier one.
  defp placeholder({%{depth: _} = fields, %{depth_live: false} = r}) do
    {Map.put(fields, :depth, nil), bump(r, :placeholder, 1)}
  end

  defp placeholder({fields, r}), do: {fields, r}

  # What the link needs to know from a line, newest first: the board's replies, its echoes and
  # its uptime (see Neptunus.Vehicle.Board.OpenROV.BoardLink.event/3).
  defp events(fields, acc) do
    acc
    |> event(fields, "rawcmd", fn _ -> {:ok, :rawcmd} end)
    |> event(
      fields,
      "crc",
      &with({:ok, c} <- OpenROV.Protocol.parse_crc(&1), do: {:ok, {:crc, c}})
    )
    |> event(fields, "cmd", &echo(&1, Map.has_key?(fields, "crc")))
    |> event(
      fields,
      "icmd",
      &with({:ok, name} <- OpenROV.Protocol.parse_echo(&1), do: {:ok, {:icmd, name}})
    )
    |> event(
      fields,
      "pong",
      &with({:ok, pong} <- OpenROV.Protocol.parse_pong(&1), do: {:ok, {:pong, pong}})
    )
    |> event(fields, :board_time, fn s -> {:ok, {:board_time, round(s * 1000)}} end)
    |> event(fields, "boot", fn _ -> {:ok, :boot} end)
    |> Enum.take(@max_events)
  end

  # An echo; a 2.5 board given a CRC-prefixed command echoes it with the CRC byte before the
  # name (and does not recognise it).
  defp echo(value, crc?) do
    with :error <- OpenROV.Protocol.parse_call(value),
         {:ok, name} <- OpenROV.Protocol.parse_echo(value) do
      # cut short: counted, but it confirms no setting
      {:ok, {:echo, name, nil, crc?}}
    else
      {:ok, name, args} ->
        {:ok, {:echo, name, args, crc?}}

      :error ->
        with false <- crc?,
             <<_crc, rest::binary>> <- value,
             {:ok, name} <- OpenROV.Protocol.parse_echo(rest),
             do: {:ok, {:echo_prefixed, name}},
             else: (_ -> :error)
    end
  end

  defp event(acc, fields, key, parse) do
    with {:ok, value} <- Map.fetch(fields, key),
         {:ok, event} <- parse.(value) do
      [event | acc]
    else
      _ -> acc
    end
  end

  @doc "The events seen since the last call, oldest first, and the readings without them."
  @spec take_events(t()) :: {[event()], t()}
  def take_events(%__MODULE__{events: events} = r), do: {Enum.reverse(events), %{r | events: []}}

  defp bump(r, _key, 0), do: r
  defp bump(r, key, n), do: %{r | counters: Map.update!(r.counters, key, &(&1 + n))}

  @doc "Wild points so far (all reasons but malformed)."
  @spec wild_points(t()) :: non_neg_integer()
  def wild_points(%__MODULE__{counters: c}), do: c.out_of_range + c.not_a_number + c.key_as_value
end
