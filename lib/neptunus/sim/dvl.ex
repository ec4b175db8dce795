defmodule Neptunus.Sim.DVL do
  @moduledoc """
  A simulated Doppler velocity log (Water Linked DVL A50-like) measuring the simulated
  vehicle's true state, with what makes a real one hard. Pure: `step/3` is called with the
  simulation's time and true state and returns the reports due by then — in the shape of
  `Neptunus.Protocol.WaterLinkedDVL`'s decoded reports, so `Neptunus.Sim.DVLServer` sends them
  as the real protocol's lines and the headless runner hands them to the same driver core. All
  randomness is a seeded `:rand` state inside the value.

  ## What it measures

    * **Velocity over the bottom** in the vehicle frame (`vx, vy, vz` = the true `u, v, w`)
      every `1/rate` s (default 8 Hz), with white noise of standard deviation
      `noise + noise_per_m · altitude` (default 3 mm/s + 0.5 mm/s per metre of altitude); the
      report's `fom` is that standard deviation and its `covariance` `fom² · I`.
    * **Altitude** = `seabed − depth` (a flat seabed at `seabed` m, default 30), ± 1 cm.
    * **Dead reckoning** (`position_local`, 5 Hz): its own integration of its velocities
      rotated by its heading, which drifts (`gyro_drift`, rad/s, default 0.0005: an
      uncalibrated gyro), from where it was at its last `reset_dead_reckoning`.

  ## What makes it hard

    * **Bottom lock** only within `min_altitude .. max_altitude` (default 0.05 .. 50 m, the
      A50's); out of range the reports say `velocity_valid: false` (velocities 0, altitude
      −1, a large `fom`), and lock comes back `relock` s (default 1) after the vehicle is in
      range again.
    * **Dropouts**: with probability `dropout` (default 0.02) a report has no lock (a ping
      lost to a fish, bubbles, a steep slope).
    * **Latency**: each report is sent `latency + 2·altitude/1480` s (default 30 ms of
      processing plus the echo's flight) after its time of validity; `time_of_validity` and
      `time_of_transmission` say so, in the DVL's own clock (`epoch_us` + simulated time).

  ## Commands

  `command/3` answers `reset_dead_reckoning` at once (the dead reckoning restarts at zero)
  and `calibrate_gyro` after `calibrate_s` (default 2 s; it fails if the vehicle moves faster
  than 5 cm/s meanwhile, as the DVL must be still); `get_config` with its configuration;
  anything else with `success: false`.
  """

  @defaults %{
    rate: 8.0,
    seabed: 30.0,
    min_altitude: 0.05,
    max_altitude: 50.0,
    noise: 0.003,
    noise_per_m: 0.0005,
    dropout: 0.02,
    relock: 1.0,
    latency: 0.03,
    gyro_drift: 0.0005,
    calibrate_s: 2.0,
    epoch_us: 0
  }
  @position_rate 5.0
  @sound 1480.0
  @invalid_fom 2.707

  @enforce_keys [:config, :rand]
  defstruct [
    :config,
    :rand,
    :next_ping,
    :next_position,
    :last_ping,
    :lock_from,
    :calibrating,
    queue: [],
    dr: %{x: 0.0, y: 0.0, z0: nil, yaw_error: 0.0, t: nil},
    pings: 0
  ]

  @type truth :: %{
          required(:x) => float(),
          required(:y) => float(),
          required(:z) => float(),
          required(:psi) => float(),
          required(:u) => float(),
          required(:v) => float(),
          required(:w) => float(),
          optional(atom()) => term()
        }

  @type report ::
          {:velocity, Neptunus.Protocol.WaterLinkedDVL.velocity()}
          | {:position_local, Neptunus.Protocol.WaterLinkedDVL.position_local()}
          | {:response, Neptunus.Protocol.WaterLinkedDVL.response()}

  @typedoc """
  * `config` — the settings (see the moduledoc), `rand` — the random state
  * `next_ping`, `next_position` — when the next velocity and dead-reckoning reports are
    measured; `last_ping` — the time of the previous one; `lock_from` — when bottom lock
    (re)starts (nil: no lock)
  * `queue` — `{send_at, report}` measured but not yet sent, in order
  * `dr` — the dead reckoning (its position, the heading error of its gyro, last time)
  * `calibrating` — `{done_at, started_at}` while a gyro calibration runs
  """
  @type t :: %__MODULE__{
          config: map(),
          rand: :rand.state(),
          next_ping: float() | nil,
          next_position: float() | nil,
          last_ping: float() | nil,
          lock_from: float() | nil,
          calibrating: {float(), float()} | nil,
          queue: [{float(), report()}],
          dr: map(),
          pings: non_neg_integer()
        }

  @doc "The default settings."
  @spec defaults() :: map()
  def defaults, do: @defaults

  @doc "A DVL with settings overriding `defaults/0` (a keyword or map), seeded with `seed`."
  @spec new(keyword() | map(), integer()) :: t()
  def new(opts \\ [], seed \\ 0) do
    config = Neptunus.Sim.device_settings(@defaults, opts, "DVL")
    %__MODULE__{config: config, rand: :rand.seed_s(:exsss, {seed, 0xD71, 0x5EA})}
  end

  @doc """
  Advances to time `t` (s) with the vehicle's true state: measures what is due and returns
  the reports whose transmission is due by `t`, in order.
  """
  @spec step(t(), float(), truth()) :: {[report()], t()}
  def step(%__MODULE__{} = dvl, t, truth) do
    dvl =
      dvl
      |> start(t)
      |> lock(t, truth)
      |> ping(t, truth)
      |> dead_reckon(t, truth)
      |> position(t, truth)
      |> calibration(t, truth)

    {due, later} = Enum.split_while(dvl.queue, fn {at, _} -> at <= t end)
    {Enum.map(due, &elem(&1, 1)), %{dvl | queue: later}}
  end

  defp start(%__MODULE__{next_ping: nil} = dvl, t),
    do: %{dvl | next_ping: t, next_position: t, last_ping: nil}

  defp start(dvl, _t), do: dvl

  defp altitude(dvl, truth), do: dvl.config.seabed - truth.z

  defp in_range?(dvl, truth) do
    a = altitude(dvl, truth)
    a >= dvl.config.min_altitude and a <= dvl.config.max_altitude
  end

  # lock is lost at once out of range, and comes back `relock` s after it is in range again
  defp lock(dvl, t, truth) do
    case {in_range?(dvl, truth), dvl.lock_from} do
      {false, _} -> %{dvl | lock_from: nil}
      {true, nil} -> %{dvl | lock_from: if(dvl.pings == 0, do: t, else: t + dvl.config.relock)}
      {true, _} -> dvl
    end
  end

  defp ping(%__MODULE__{next_ping: next} = dvl, t, _truth) when t < next, do: dvl

  defp ping(dvl, t, truth) do
    c = dvl.config
    altitude = altitude(dvl, truth)
    {dropout?, rand} = chance(dvl.rand, c.dropout)
    locked? = dvl.lock_from != nil and t >= dvl.lock_from and not dropout?
    sigma = c.noise + c.noise_per_m * max(altitude, 0.0)
    {[nx, ny, nz, na], rand} = normals(rand, 4)
    time_ms = if dvl.last_ping, do: (t - dvl.last_ping) * 1000.0, else: 1000.0 / c.rate
    flight = 2.0 * max(altitude, 0.0) / @sound
    tov = c.epoch_us + round(t * 1.0e6)
    send_at = t + c.latency + flight

    report =
      if locked? do
        %{
          vx: truth.u + sigma * nx,
          vy: truth.v + sigma * ny,
          vz: truth.w + sigma * nz,
          fom: sigma,
          covariance: diag(sigma * sigma),
          altitude: altitude + 0.01 * na,
          valid: true
        }
      else
        %{
          vx: 0.0,
          vy: 0.0,
          vz: 0.0,
          fom: @invalid_fom,
          covariance: diag(@invalid_fom * @invalid_fom),
          altitude: -1.0,
          valid: false
        }
      end
      |> Map.merge(%{
        status: 0,
        time_ms: time_ms,
        time_of_validity_us: tov,
        time_of_transmission_us: c.epoch_us + round(send_at * 1.0e6),
        tracking: :bottom,
        transducers: beams(locked?, altitude)
      })

    %{
      dvl
      | rand: rand,
        last_ping: t,
        next_ping: dvl.next_ping + 1.0 / c.rate,
        pings: dvl.pings + 1,
        queue: enqueue(dvl.queue, send_at, {:velocity, report})
    }
    |> then(fn dvl ->
      # the dead reckoning integrates what the DVL measured (its own noise included)
      if locked?, do: put_in(dvl.dr[:velocity], {report.vx, report.vy}), else: dvl
    end)
  end

  # the four beams, 22.5° off vertical, each seeing the flat seabed
  defp beams(locked?, altitude) do
    distance = if locked?, do: altitude / :math.cos(22.5 * :math.pi() / 180), else: -1.0

    for id <- 0..3 do
      %{
        id: id,
        velocity: 0.0,
        distance: distance,
        rssi: if(locked?, do: -35.0, else: -95.0),
        nsd: -95.0,
        beam_valid: locked?
      }
    end
  end

  defp diag(x), do: [[x, 0.0, 0.0], [0.0, x, 0.0], [0.0, 0.0, x]]

  # the DVL's own dead reckoning: its last measured velocity, rotated by its drifting heading
  defp dead_reckon(%__MODULE__{dr: %{t: nil} = dr} = dvl, t, truth),
    do: %{dvl | dr: %{dr | t: t, z0: truth.z}}

  defp dead_reckon(%__MODULE__{dr: dr} = dvl, t, truth) do
    dt = t - dr.t
    yaw_error = dr.yaw_error + dvl.config.gyro_drift * dt
    {vx, vy} = Map.get(dr, :velocity, {0.0, 0.0})
    yaw = truth.psi + yaw_error
    {c, s} = {:math.cos(yaw), :math.sin(yaw)}

    %{
      dvl
      | dr: %{
          dr
          | x: dr.x + (c * vx - s * vy) * dt,
            y: dr.y + (s * vx + c * vy) * dt,
            yaw_error: yaw_error,
            t: t
        }
    }
  end

  defp position(%__MODULE__{next_position: next} = dvl, t, _truth) when t < next, do: dvl

  defp position(%__MODULE__{dr: dr} = dvl, t, truth) do
    report = %{
      ts: dvl.config.epoch_us / 1.0e6 + t,
      x: dr.x,
      y: dr.y,
      z: truth.z - dr.z0,
      std: 0.01 + 0.001 * dvl.pings,
      roll: Map.get(truth, :phi, 0.0),
      pitch: Map.get(truth, :theta, 0.0),
      yaw: Neptunus.Dynamics.wrap_pi(truth.psi + dr.yaw_error),
      status: 0
    }

    %{
      dvl
      | next_position: dvl.next_position + 1.0 / @position_rate,
        queue: enqueue(dvl.queue, t + dvl.config.latency, {:position_local, report})
    }
  end

  defp calibration(%__MODULE__{calibrating: {done_at, _}} = dvl, t, truth) do
    speed = :math.sqrt(truth.u * truth.u + truth.v * truth.v + truth.w * truth.w)

    cond do
      speed > 0.05 ->
        respond(
          %{dvl | calibrating: nil},
          t,
          "calibrate_gyro",
          false,
          "the DVL moved while calibrating its gyro: keep it still"
        )

      t >= done_at ->
        dr = %{dvl.dr | yaw_error: 0.0}

        respond(
          %{dvl | calibrating: nil, dr: dr, config: %{dvl.config | gyro_drift: 0.0}},
          t,
          "calibrate_gyro",
          true,
          ""
        )

      true ->
        dvl
    end
  end

  defp calibration(dvl, _t, _truth), do: dvl

  @doc """
  A command from the driver (its name as sent, see `Neptunus.Protocol.WaterLinkedDVL`) at
  time `t`: its response is queued (sent by the next `step/3` due).
  """
  @spec command(t(), float(), String.t() | {:unknown, String.t()}) :: t()
  def command(dvl, t, "reset_dead_reckoning") do
    dvl = %{dvl | dr: %{dvl.dr | x: 0.0, y: 0.0, z0: nil, t: nil}}
    respond(dvl, t, "reset_dead_reckoning", true, "")
  end

  def command(%__MODULE__{calibrating: nil} = dvl, t, "calibrate_gyro"),
    do: %{dvl | calibrating: {t + dvl.config.calibrate_s, t}}

  def command(dvl, t, "calibrate_gyro"),
    do: respond(dvl, t, "calibrate_gyro", false, "a gyro calibration is running already")

  def command(dvl, t, "get_config") do
    result = %{
      speed_of_sound: @sound,
      acoustic_enabled: true,
      dark_mode_enabled: false,
      mounting_rotation_offset: 0.0,
      range_mode: "auto",
      periodic_cycling_enabled: true
    }

    respond(dvl, t, "get_config", true, "", result)
  end

  def command(dvl, t, "trigger_ping"), do: respond(dvl, t, "trigger_ping", true, "")

  def command(dvl, t, {:unknown, name}),
    do: respond(dvl, t, name, false, "unknown command #{inspect(name)}")

  defp respond(dvl, t, to, success, message, result \\ nil) do
    response = %{to: to, success: success, error_message: message, result: result}
    %{dvl | queue: enqueue(dvl.queue, t, {:response, response})}
  end

  # the queue stays in send order (a response may overtake a report still in flight)
  defp enqueue(queue, at, report) do
    {before, later} = Enum.split_while(queue, fn {a, _} -> a <= at end)
    before ++ [{at, report} | later]
  end

  defp chance(rand, p) when p <= 0, do: {false, rand}

  defp chance(rand, p) do
    {x, rand} = :rand.uniform_s(rand)
    {x < p, rand}
  end

  defp normals(rand, n) do
    Enum.map_reduce(1..n, rand, fn _, rand -> :rand.normal_s(rand) end)
  end
end
