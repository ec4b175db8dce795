defmodule Neptunus.Clock do
  @moduledoc """
  The node's one time base: every process reads the time here, and nowhere else.

    * **Inside the node, times are integer milliseconds of the VM's monotonic clock**
      (`monotonic_ms/0`), in names that end in `_ms` (`last_seen_ms`, `deadline_ms`,
      `idle_timeout_ms`); durations are differences of these. The monotonic clock never jumps
      when the system clock is set (NTP, a BeagleBone booting without a battery-backed clock),
      so timeouts, deadmen and rate windows stay right.
    * **Wall-clock time only where a date is shown or stored** (`wall_ms/0`, milliseconds
      since the Unix epoch): a recording's entries, a log line's `at`, when a pilot got
      control, a login token's expiry (in seconds). Such names end in `_wall_ms` (or say
      so in their doc where the wire fixes the name, like `at` and `since`).
    * **Native units only in `Neptunus.Periodic`'s schedule** (`monotonic_native/0`): a
      period of one second divided by the rate is exact there at any rate, where whole
      milliseconds would drift (1000 / 30 Hz). Its users pass the native time they read
      through, and convert for anything else.
    * **Pure cores that also run on simulated time** (`Neptunus.Control.Core`,
      `Neptunus.Sim`, the scenario runner) take seconds (SI, a float): their process converts
      at its edge (`monotonic_ms() / 1000`).

  At the edges the time is converted once: telemetry's `sent_at` and the clock-sync
  reply are wall-clock milliseconds with a fraction (`wall_us/0`, for the browser's latency
  figures); the C port program counts its own milliseconds; recordings store `wall_ms/0`.
  """

  @doc "Now, in integer milliseconds of the monotonic clock (the node's time base)."
  @spec monotonic_ms() :: integer()
  def monotonic_ms, do: System.monotonic_time(:millisecond)

  @doc "Now, in native units of the monotonic clock (`Neptunus.Periodic`'s schedule only)."
  @spec monotonic_native() :: integer()
  def monotonic_native, do: System.monotonic_time()

  @doc "Microseconds since the VM started (monotonic)."
  @spec uptime_us() :: non_neg_integer()
  def uptime_us do
    System.convert_time_unit(
      System.monotonic_time() - :erlang.system_info(:start_time),
      :native,
      :microsecond
    )
  end

  @doc "The wall clock: milliseconds since the Unix epoch (for dates shown or stored)."
  @spec wall_ms() :: integer()
  def wall_ms, do: System.os_time(:millisecond)

  @doc "The wall clock in microseconds since the Unix epoch (for sub-millisecond edges)."
  @spec wall_us() :: integer()
  def wall_us, do: System.os_time(:microsecond)
end
