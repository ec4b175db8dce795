# Shared by the benchmarks that write recordings: a telemetry payload of a live vehicle's shape.
defmodule Bench.TelemetrySample do
  @moduledoc false

  @doc "The `i`-th telemetry payload of a 20 Hz dive (Neptunus.Vehicle.Telemetry's shape)."
  def payload(i) do
    t = i * 0.05
    f = fn k -> :math.sin(t / k) end

    %{
      t: t,
      sent_at: 1_795_000_000_000 + i * 50.0,
      measurement: %{
        depth: f.(3),
        heading: f.(5) + 1,
        roll: f.(7),
        pitch: f.(11),
        voltage: 12.1,
        current: 0.5
      },
      estimate: %{depth: f.(3), depth_rate: f.(13), heading: f.(5) + 1, yaw_rate: f.(17)},
      wild_points: %{
        total: 3,
        by_field: %{depth: 1, heading: 2},
        by_reason: %{out_of_range: 1, rate_of_change: 2},
        reacquired: 0
      },
      sim: %{
        x: f.(19),
        y: f.(23),
        z: f.(3),
        phi: 0.0,
        theta: 0.0,
        psi: f.(5),
        u: 0.1,
        v: 0.0,
        w: 0.0,
        p: 0.0,
        q: 0.0,
        r: 0.0
      },
      command: %{surge: 0.2, heave: 0.0, yaw: f.(29)},
      thrusters: %{
        port: 0.1,
        vertical: 0.0,
        starboard: 0.1,
        port_us: 1550,
        vertical_us: 1500,
        starboard_us: 1550
      },
      control: %{
        mode: "motion",
        gain: 0.5,
        lights: 0,
        laser: 0,
        tilt: 0.0,
        run_mode: "normal",
        autopilot: %{depth: 1.0, heading: nil, position: nil}
      },
      autopilot: %{
        depth: %{setpoint: 1.0, output: f.(31), overridden: false},
        heading: nil,
        position: nil
      },
      link: %{up: true, reason: "open"},
      recording: %{on: true, error: nil}
    }
  end
end
