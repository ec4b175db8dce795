defmodule Neptunus.GCS.Scheduler do
  @moduledoc """
  Which of a vehicle's streamed messages one ground station gets when (pure): each message
  at its own interval, per vehicle, changed by the ground station with
  `MAV_CMD_SET_MESSAGE_INTERVAL` (and the legacy REQUEST_DATA_STREAM).

  The vehicle's messages are built on every tick of its source (20 Hz, `Neptunus.GCS.Source`),
  so a message goes out on the first tick at or after its time; a tick up to
  20 ms early counts (a timer firing a little early would otherwise stretch a 100 ms
  interval to 150). Intervals are at least the tick (50 ms: faster than the vehicle's state
  changes is not possible) and at most 60 s.

  Default intervals — what QGroundControl and Cockpit expect of an ArduSub (its stream
  defaults):

  | message | interval |
  |---|---|
  | HEARTBEAT, CONTROL_STATUS, SYSTEM_TIME | 1 s |
  | SYS_STATUS, SCALED_PRESSURE, SERVO_OUTPUT_RAW, NAMED_VALUE_FLOAT | 500 ms |
  | ATTITUDE, VFR_HUD | 100 ms |
  | LOCAL_POSITION_NED, GLOBAL_POSITION_INT | 333 ms |
  """

  alias Neptunus.Protocol.MAVLink.Messages

  @defaults %{
    heartbeat: 1000,
    control_status: 1000,
    system_time: 1000,
    sys_status: 500,
    scaled_pressure: 500,
    servo_output_raw: 500,
    named_value_float: 500,
    attitude: 100,
    vfr_hud: 100,
    local_position_ned: 333,
    global_position_int: 333
  }
  @early_ms 20
  @min_ms 50
  @max_ms 60_000

  # REQUEST_DATA_STREAM's streams (MAV_DATA_STREAM) and the messages in each, as ArduSub
  # groups them; 0 (ALL) is all of them
  @streams %{
    1 => [:scaled_pressure],
    2 => [:sys_status, :control_status],
    3 => [:servo_output_raw],
    6 => [:local_position_ned, :global_position_int],
    10 => [:attitude],
    11 => [:vfr_hud],
    12 => [:named_value_float, :system_time]
  }

  defstruct intervals: %{}, next: %{}

  @typedoc """
  * `intervals` — `%{{sysid, name} => ms | :off}`, the ground station's own choices (the
    defaults otherwise)
  * `next` — `%{{sysid, name} => ms}`, when each message is due next
  """
  @type t :: %__MODULE__{
          intervals: %{{1..255, atom()} => pos_integer() | :off},
          next: %{{1..255, atom()} => integer()}
        }

  @doc "A ground station's schedule: every message at its default interval."
  @spec new() :: t()
  def new, do: %__MODULE__{}

  @doc "The messages streamed, by name."
  @spec streamed() :: [atom()]
  def streamed, do: Map.keys(@defaults)

  @doc "The default interval of a streamed message (ms), or nil."
  @spec default_ms(atom()) :: pos_integer() | nil
  def default_ms(name), do: Map.get(@defaults, name)

  @doc """
  Which of the messages `available` (names) vehicle `sysid` has at this tick are due at
  `now_ms`; each due one is scheduled one interval on.
  """
  @spec due(t(), 1..255, [atom()], integer()) :: {t(), [atom()]}
  def due(%__MODULE__{} = s, sysid, available, now_ms) do
    Enum.reduce(available, {s, []}, fn name, {s, due} ->
      key = {sysid, name}

      case interval(s, key) do
        :off ->
          {s, due}

        nil ->
          {s, due}

        interval ->
          next = Map.get(s.next, key, now_ms)

          if now_ms >= next - @early_ms do
            # a tick late keeps the rhythm; one far behind starts again from now
            following = if next + interval > now_ms, do: next + interval, else: now_ms + interval
            {%{s | next: Map.put(s.next, key, following)}, [name | due]}
          else
            {s, due}
          end
      end
    end)
    |> then(fn {s, due} -> {s, Enum.reverse(due)} end)
  end

  defp interval(s, key) do
    case Map.fetch(s.intervals, key) do
      {:ok, interval} -> interval
      :error -> Map.get(@defaults, elem(key, 1))
    end
  end

  @doc """
  `MAV_CMD_SET_MESSAGE_INTERVAL` for vehicle `sysid`: message id `message_id`, interval in
  µs (`-1` stops it, `0` restores its default). `{:error, reason}` for a message this vehicle
  does not stream.

      iex> s = Neptunus.GCS.Scheduler.new()
      iex> {:ok, s} = Neptunus.GCS.Scheduler.set_interval(s, 1, 30, 200_000)
      iex> Neptunus.GCS.Scheduler.interval_us(s, 1, 30)
      200000
      iex> Neptunus.GCS.Scheduler.set_interval(s, 1, 147, 100_000)
      {:error, "message 147 is not streamed here"}
  """
  @spec set_interval(t(), 1..255, integer(), number()) :: {:ok, t()} | {:error, String.t()}
  def set_interval(s, sysid, message_id, interval_us) do
    with {:ok, name} <- streamed_name(message_id) do
      key = {sysid, name}

      interval =
        cond do
          interval_us < 0 -> :off
          interval_us == 0 -> nil
          true -> interval_us |> div1000() |> max(@min_ms) |> min(@max_ms)
        end

      intervals =
        if interval, do: Map.put(s.intervals, key, interval), else: Map.delete(s.intervals, key)

      # a new interval starts now (a faster one would otherwise wait for the old time)
      {:ok, %{s | intervals: intervals, next: Map.delete(s.next, key)}}
    end
  end

  @doc "The interval of message `message_id` for vehicle `sysid` in µs (`-1`: off), or an error."
  @spec interval_us(t(), 1..255, integer()) :: integer() | {:error, String.t()}
  def interval_us(s, sysid, message_id) do
    with {:ok, name} <- streamed_name(message_id) do
      case interval(s, {sysid, name}) do
        :off -> -1
        ms -> ms * 1000
      end
    end
  end

  @doc """
  The legacy REQUEST_DATA_STREAM: stream `stream_id` (MAV_DATA_STREAM; 0 = all) of vehicle
  `sysid` at `rate_hz` (start) or off (stop). A rate of 0 with start restores the defaults.
  """
  @spec data_stream(t(), 1..255, integer(), integer(), boolean()) :: t()
  def data_stream(s, sysid, stream_id, rate_hz, start?) do
    names =
      case stream_id do
        0 -> @streams |> Map.values() |> List.flatten()
        id -> Map.get(@streams, id, [])
      end

    Enum.reduce(names, s, fn name, s ->
      key = {sysid, name}

      intervals =
        cond do
          not start? ->
            Map.put(s.intervals, key, :off)

          rate_hz <= 0 ->
            Map.delete(s.intervals, key)

          true ->
            Map.put(s.intervals, key, (1000 / rate_hz) |> round() |> max(@min_ms) |> min(@max_ms))
        end

      %{s | intervals: intervals, next: Map.delete(s.next, key)}
    end)
  end

  @doc "The name of a streamed message's id, or why not."
  @spec streamed_name(integer()) :: {:ok, atom()} | {:error, String.t()}
  def streamed_name(message_id) do
    case is_integer(message_id) and Messages.get(message_id) do
      %{name: name} when is_map_key(@defaults, name) -> {:ok, name}
      _ -> {:error, "message #{message_id} is not streamed here"}
    end
  end

  defp div1000(us), do: round(us / 1000)
end
