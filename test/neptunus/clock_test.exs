defmodule Neptunus.ClockTest do
  # One time base (Neptunus.Clock): no other module of the node reads a clock.
  use ExUnit.Case, async: true

  alias Neptunus.Clock

  @clock_reads [
    {System, :monotonic_time},
    {System, :os_time},
    {System, :system_time},
    {:erlang, :monotonic_time},
    {:erlang, :system_time},
    {:erlang, :timestamp},
    {:erlang, :now},
    {:os, :system_time},
    {:os, :timestamp},
    {:os, :perf_counter}
  ]

  test "no module but Neptunus.Clock reads a clock" do
    {:ok, modules} = :application.get_key(:neptunus, :modules)

    reads =
      for module <- modules,
          module != Clock,
          not test_support?(module),
          {:ok, {^module, [imports: imports]}} =
            :beam_lib.chunks(:code.which(module), [:imports]),
          {callee, fun, arity} <- imports,
          {callee, fun} in @clock_reads,
          do: "#{inspect(module)} calls #{inspect(callee)}.#{fun}/#{arity}"

    assert reads == []
  end

  test "the monotonic time base and the wall clock, in their units" do
    a = Clock.monotonic_ms()
    native = Clock.monotonic_native()
    b = Clock.monotonic_ms()
    assert is_integer(a) and b >= a
    assert_in_delta System.convert_time_unit(native, :native, :millisecond), a, b - a + 1

    wall_ms = Clock.wall_ms()
    assert_in_delta wall_ms, DateTime.to_unix(DateTime.utc_now(), :millisecond), 5_000
    assert_in_delta Clock.wall_us(), wall_ms * 1000, 5_000_000
    assert Clock.uptime_us() > 0
  end

  # the test support modules, compiled into the test build, are not the node
  defp test_support?(module) do
    name = Atom.to_string(module)

    String.starts_with?(name, "Elixir.Neptunus.Test.") or
      String.starts_with?(name, "Elixir.NeptunusWeb.Test.")
  end
end
