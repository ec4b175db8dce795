# A board that resets as its line opens, then sits in its bootloader (0.2, 0.5, 1.0 s), on both
# firmware lines: the pilot commands a forward surge (0.4 on each side thruster) at once and,
# once the board has started, again every 100 ms as a page does. For each run: the port and
# starboard ESC offsets from neutral of the first pulses the motors got, whether any pulses
# were unbalanced (> 10 µs), and how long after the open the motors first moved, on the
# board's own clock (its bootloader, then its millis). Prints figures, never asserts. Run through bench/open_reset.

defmodule Bench.OpenReset do
  alias Neptunus.{Fleet, PubSub}
  alias Neptunus.Vehicle.Board.OpenROV.{SITL, Wiring}
  alias Neptunus.Vehicle.{Control, Telemetry}

  @windows [200, 500, 1_000]
  @profiles [:openrov_25, :openrov_30]

  def main(args) do
    Logger.configure(level: :error)

    runs =
      case args do
        [n] -> String.to_integer(n)
        [] -> String.to_integer(System.get_env("RESET_RUNS", "3"))
      end

    {:ok, _} =
      Supervisor.start_link([{PubSub, encoder: NeptunusWeb.Channels.Wire}, {Fleet, []}],
        strategy: :one_for_one
      )

    {load, _} = System.cmd("cat", ["/proc/loadavg"])

    IO.puts(
      "Board reset on open — #{System.schedulers_online()} schedulers, load #{String.trim(load)}\n" <>
        "forward surge 0.4 per side thruster (go(1300,1500,1700)): straight is 230/230 µs\n"
    )

    IO.puts(
      "| firmware | bootloader | runs | first pulses port/starboard µs | unbalanced | moved after the open (ms, min / median / max) |"
    )

    IO.puts("|---|---|---|---|---|---|")

    for profile <- @profiles, window <- @windows do
      results = for i <- 1..runs, do: run(profile, window, i)
      times = results |> Enum.map(& &1.since_open_ms) |> Enum.sort()
      offsets = results |> Enum.map(&"#{elem(&1.first, 0)}/#{elem(&1.first, 1)}") |> Enum.uniq()
      unbalanced = Enum.count(results, & &1.unbalanced?)

      IO.puts(
        "| #{name(profile)} | #{window} ms | #{runs} | " <>
          "#{Enum.join(offsets, ", ")} | #{unbalanced} | " <>
          "#{List.first(times)} / #{Enum.at(times, div(length(times), 2))} / #{List.last(times)} |"
      )
    end
  end

  defp name(:openrov_25), do: "openrov-2.5"
  defp name(:openrov_30), do: "openrov-30"

  defp run(profile, window, i) do
    id = "reset-#{profile}-#{window}-#{i}"
    PubSub.subscribe(Telemetry.topic(id))

    {:ok, _} =
      Fleet.start_vehicle(%{
        id: id,
        board: :sitl,
        wiring: Wiring.default(),
        firmware: profile,
        reset_on_open: true,
        bootloader_ms: window,
        sim: [noise: false]
      })

    receive do
      {:pubsub, _, "link", %{up: true}} -> :ok
    after
      10_000 -> raise "no link for #{id}"
    end

    surge = %{"mode" => "motion", "surge" => 0.8, "heave" => 0, "yaw" => 0}
    {:ok, _} = Control.thrust(id, surge)
    wait(id, "the board's start", fn -> started?(SITL.Device.state(id).firmware) end)
    # then as a pilot's page does: the stick again every 100 ms (a command the board lost on
    # its line is sent again)
    drive(id, surge, fn -> moving?(SITL.Device.state(id).firmware.esc_us) end)

    fw = SITL.Device.state(id).firmware
    moved = for {m, esc} <- Enum.reverse(fw.esc_log), moving?(esc), do: {m, offsets(esc)}
    [{first_ms, first} | _] = moved
    Fleet.stop_vehicle(id)
    PubSub.unsubscribe(Telemetry.topic(id))

    %{
      first: first,
      since_open_ms: window + first_ms,
      unbalanced?: Enum.any?(moved, fn {_m, {p, s}} -> abs(p - s) > 10 end)
    }
  end

  defp started?(fw), do: SITL.Firmware.millis(fw, Neptunus.Clock.monotonic_ms()) > fw.setup_ms
  defp moving?({p, _v, s}), do: p != 1500 or s != 1500
  defp offsets({p, _v, s}), do: {abs(p - 1500), abs(s - 1500)}

  defp drive(id, surge, moved?, left \\ 100) do
    {:ok, _} = Control.thrust(id, surge)

    cond do
      Enum.any?(1..20, fn _ -> moved?.() or (Process.sleep(5) && false) end) -> :ok
      left == 0 -> wait(id, "the motors to move", moved?, 0)
      true -> drive(id, surge, moved?, left - 1)
    end
  end

  defp wait(id, what, fun, left \\ 10_000) do
    cond do
      fun.() ->
        :ok

      left <= 0 ->
        fw = SITL.Device.state(id).firmware

        raise "#{id}: waited 10 s for #{what}; the link: " <>
                inspect(Neptunus.Vehicle.Board.link_status(id)) <>
                "; the board: " <>
                inspect(Map.take(fw, [:target_us, :applied_us, :esc_us, :armed, :tripped]))

      true ->
        Process.sleep(5)
        wait(id, what, fun, left - 5)
    end
  end
end

Bench.OpenReset.main(System.argv())
