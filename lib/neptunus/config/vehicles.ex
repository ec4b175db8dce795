defmodule Neptunus.Config.Vehicles do
  @moduledoc """
  The vehicles (`config :neptunus, :vehicles`, see `Neptunus.Fleet`) from
  `NEPTUNUS_VEHICLES` (`id=board` pairs, default `neptunus-1=simulated`) and, per vehicle,
  `NEPTUNUS_WIRING`, `NEPTUNUS_FIRMWARE`, `NEPTUNUS_MODELS` and `NEPTUNUS_CAMERAS` (`id=value`
  pairs, every id a configured vehicle).

  Boards: `simulated` (the built-in simulator), `sitl` (the simulator behind a pseudo-terminal
  speaking the OpenROV protocol, through the real board link), `uart:DEVICE[@BAUD]` (a real
  board, e.g. `uart:/dev/ttyO1@115200`; baud 1200 … 921600, default 115200) and `mavlink:LINK`
  (an ArduSub vehicle over MAVLink, `Neptunus.Vehicle.Board.MAVLink`, docs/MAVLINK.md) where
  LINK is `udp:ADDRESS:PORT` (listen on a local address for the vehicle's stream and answer
  whoever sent the last datagram, e.g. `udp:0.0.0.0:14550`), `udpout:HOST:PORT` (send to the
  vehicle), `tcp:HOST:PORT` (connect; ArduPilot SITL listens on 5760) or
  `serial:DEVICE[@BAUD]` (through the `neptunus_uart` port program, as `uart`). Vehicle ids
  are 1..32 characters of `a-z A-Z 0-9 _ -`.

  MAVLink ids (`mavlink` vehicles): `NEPTUNUS_MAVLINK_IDS=id=SYSTEM/COMPONENT` pairs, our own
  system and component ids on that vehicle's link, each in 1..255; default `255/190` (ArduSub
  takes pilot input only from the ground station system id `MAV_GCS_SYSID`, 255 by default).
  `NEPTUNUS_MAVLINK_DISARM_DELAY=id=SECONDS` (0.1..60, default 2): how long after losing its
  pilot (disconnect, deadman, release) a mavlink vehicle is disarmed unless a new pilot takes
  the helm.

  SITL bootloader (`sitl` vehicles): `NEPTUNUS_SITL_BOOTLOADER=id=MS` pairs (1..10000): the
  simulated board reboots whenever its line is opened, as a USB Arduino does, and its
  bootloader loses what arrives for MS milliseconds (see docs/OPENROV.md, Settings). Without
  it the simulated board is already running when the line opens.

  Wiring (`sitl` and `uart` vehicles, see `Neptunus.Vehicle.Board.OpenROV.Wiring`): the motors in
  `go()` order separated by `/`, `-` before a reversed one, optionally `:FORWARD:REVERSE` motor
  modifiers after a motor (percent, multiples of 100, default 100 and 100; sent as
  `mtrmod1`/`mtrmod2`), optionally `/direct` or `/ramp` (`go()`'s 4th argument 1 or 0; no effect on
  OpenROV 2.5.x and 30.x firmware, whose values apply at its next 50 ms tick either way); default
  `-port/vertical/starboard/direct` (the thesis' Neptunus). Example:
  `NEPTUNUS_WIRING=rov=port/vertical/-starboard:100:200`.

  Firmware (`sitl` and `uart` vehicles, see docs/OPENROV.md): `openrov-2.5` (OpenROV 2.5.x:
  plain `;`-terminated commands) or `openrov-30` (OpenROV 30.x: every command prefixed with
  its CRC-8 byte). Example: `NEPTUNUS_FIRMWARE=rov=openrov-30`. The board link reports a
  board whose output shows the other line; it never switches on its own.

  Model: the vehicle's parameter set in `priv/vehicles/` (`neptunus`, `thesis-4dof`, …, see
  `Neptunus.Dynamics.Params`): what its simulator flies (`simulated` and `sitl` boards, and
  run mode simulator on a real board) and the model of its navigation filter. Example:
  `NEPTUNUS_MODELS=a=thesis-4dof`.

  Position sources: `NEPTUNUS_POSITION` (`Neptunus.Config.Position`): every vehicle gets a
  `position` list (by default the simulated DVL and USBL on a simulated or sitl vehicle).

  Camera (see `Neptunus.Camera.Source`): `v4l2:DEVICE[@h264|@mjpeg][@WxH][@FPS]` (a webcam
  through ffmpeg, its own H.264 or MJPEG passed on), `rtsp://…` (an IP camera's H.264),
  `sim[@h264|@mjpeg][@WxH][@FPS][@bottom=M]` (the simulator's view), `testsrc[…]` (ffmpeg's
  test pattern), `exec:PROGRAM [ARGS]` / `exec@h264:PROGRAM [ARGS]` (any program writing MJPEG
  or H.264 to its output), or `none`. Simulated and SITL vehicles have the `sim` camera
  unless configured otherwise. Example: `NEPTUNUS_CAMERAS=rov=v4l2:/dev/video0@1280x720@30`.
  """

  alias Neptunus.Config
  alias Neptunus.Vehicle.Board

  @typedoc """
  A vehicle: its `id`, its `board` (a type of `Neptunus.Vehicle.Board`), the options its
  board's spec gives (`Neptunus.Vehicle.Board.parse/1`: `device` and `baud` for `uart`,
  `link` for `mavlink`), the settings its board takes (`Neptunus.Vehicle.Board.takes?/2`:
  `wiring`, `firmware`, `system` and `component`, …), `sim: [vehicle: name]` when
  `NEPTUNUS_MODELS` names its parameter set, its `camera` and its `position` sources.
  """
  @type vehicle :: %{
          required(:id) => String.t(),
          required(:board) => atom(),
          optional(:sim) => keyword(),
          optional(:camera) => Neptunus.Camera.Source.t(),
          optional(atom()) => term()
        }

  @default_vehicles "neptunus-1=simulated"

  @doc """
  Vehicles from `NEPTUNUS_VEHICLES` (and their wiring from `NEPTUNUS_WIRING`).

      iex> Neptunus.Config.Vehicles.vehicles!(%{"NEPTUNUS_VEHICLES" => "a=simulated, b=simulated"})
      ...> |> Enum.map(&Map.take(&1, [:id, :board]))
      [%{id: "a", board: :simulated}, %{id: "b", board: :simulated}]

      iex> [rov] = Neptunus.Config.Vehicles.vehicles!(%{"NEPTUNUS_VEHICLES" => "rov=uart:/dev/ttyO1@57600"})
      iex> Map.take(rov, [:id, :board, :device, :baud])
      %{id: "rov", board: :uart, device: "/dev/ttyO1", baud: 57600}
  """
  @spec vehicles!(Config.env()) :: [vehicle()]
  def vehicles!(env) do
    spec = Map.get(env, "NEPTUNUS_VEHICLES", @default_vehicles)

    # a fleet's topside or relay node (Neptunus.Config.Cluster) hosts no vehicle
    if String.trim(spec) == "none", do: [], else: vehicles_of!(env, spec)
  end

  defp vehicles_of!(env, spec) do
    vehicles =
      spec
      |> String.split(",")
      |> Enum.map(&String.trim/1)
      |> Enum.map(&vehicle!(&1, spec))

    if vehicles == [] or spec |> String.trim() == "" do
      Config.bad!("NEPTUNUS_VEHICLES", spec, "at least one vehicle, e.g. #{@default_vehicles}")
    end

    ids = Enum.map(vehicles, & &1.id)

    case ids -- Enum.uniq(ids) do
      [] ->
        vehicles
        |> wiring!(Map.get(env, "NEPTUNUS_WIRING", ""))
        |> firmware!(Map.get(env, "NEPTUNUS_FIRMWARE", ""))
        |> models!(Map.get(env, "NEPTUNUS_MODELS", ""))
        |> cameras!(Map.get(env, "NEPTUNUS_CAMERAS", ""))
        |> mavlink_ids!(Map.get(env, "NEPTUNUS_MAVLINK_IDS", ""))
        |> mavlink_disarm_delay!(Map.get(env, "NEPTUNUS_MAVLINK_DISARM_DELAY", ""))
        |> sitl_bootloader!(Map.get(env, "NEPTUNUS_SITL_BOOTLOADER", ""))
        |> Neptunus.Config.Position.position!(env)

      [dup | _] ->
        Config.bad!("NEPTUNUS_VEHICLES", spec, "unique vehicle ids (#{inspect(dup)} repeats)")
    end
  end

  # Every vehicle whose board takes a wiring (sitl, uart) gets one: configured or the default.
  defp wiring!(vehicles, spec) do
    board_setting!(vehicles, spec, %{
      var: "NEPTUNUS_WIRING",
      expected: "id=wiring pairs, e.g. rov=-port/vertical/starboard",
      key: :wiring,
      parse: &Neptunus.Vehicle.Board.OpenROV.Wiring.parse/1,
      default: Neptunus.Vehicle.Board.OpenROV.Wiring.default()
    })
  end

  # Every vehicle whose board takes a firmware profile (sitl, uart) gets one: configured or
  # openrov-2.5.
  defp firmware!(vehicles, spec) do
    board_setting!(vehicles, spec, %{
      var: "NEPTUNUS_FIRMWARE",
      expected: "id=firmware pairs, e.g. rov=openrov-30",
      key: :firmware,
      parse: &Neptunus.Vehicle.Board.OpenROV.BoardLink.parse_profile/1,
      default: :openrov_25
    })
  end

  # A setting some boards take (Board.settings/0): `id=value` pairs parsed with `parse`, the
  # default for every such vehicle not named; refused for any other board.
  defp board_setting!(vehicles, spec, %{var: var} = setting) do
    configured =
      pairs!(var, spec, vehicles, setting.expected)
      |> Map.new(fn {vehicle, pair, text} ->
        id = taking!(vehicle, setting.key, var, spec)

        case setting.parse.(text) do
          {:ok, value} -> {id, value}
          {:error, reason} -> Config.bad!(var, spec, "#{reason} in #{inspect(pair)}")
        end
      end)

    defaults =
      for %{board: board, id: id} <- vehicles,
          Board.takes?(board, setting.key),
          into: %{},
          do: {id, setting.default}

    put_configured(vehicles, Map.merge(defaults, configured), setting.key)
  end

  # A vehicle's parameter set, for the simulator (simulated and sitl boards, and run mode
  # simulator on a real board) and for the navigation filter's model.
  defp models!(vehicles, spec) do
    configured =
      pairs!("NEPTUNUS_MODELS", spec, vehicles, "id=model pairs, e.g. rov=thesis-4dof")
      |> Map.new(fn {%{id: id}, _pair, name} ->
        if name in Neptunus.Dynamics.Params.available() do
          {id, [vehicle: name]}
        else
          Config.bad!(
            "NEPTUNUS_MODELS",
            spec,
            "a parameter set of priv/vehicles/ for #{id}: one of " <>
              Enum.join(Neptunus.Dynamics.Params.available(), ", ") <> " (got #{inspect(name)})"
          )
        end
      end)

    put_configured(vehicles, configured, :sim)
  end

  # A vehicle's camera source (Neptunus.Camera.Source): the configured one, `none`, or by
  # default the simulated camera for a vehicle in the simulator (simulated, sitl).
  defp cameras!(vehicles, spec) do
    configured =
      pairs!("NEPTUNUS_CAMERAS", spec, vehicles, "id=source pairs, e.g. rov=v4l2:/dev/video0")
      |> Map.new(fn {%{id: id}, pair, text} ->
        case text do
          "none" ->
            {id, nil}

          _ ->
            case Neptunus.Camera.Source.parse(text) do
              {:ok, source} ->
                {id, source}

              {:error, reason} ->
                Config.bad!("NEPTUNUS_CAMERAS", spec, "#{reason} in #{inspect(pair)}")
            end
        end
      end)

    {:ok, sim} = Neptunus.Camera.Source.parse("sim")

    defaults =
      for %{id: id, board: board} <- vehicles,
          Board.takes?(board, :sim_sources),
          into: %{},
          do: {id, sim}

    put_configured(
      vehicles,
      defaults |> Map.merge(configured) |> Map.reject(&is_nil(elem(&1, 1))),
      :camera
    )
  end

  # Our own MAVLink system and component ids per mavlink vehicle: `id=SYSTEM/COMPONENT`,
  # default 255/190 (a ground station: ArduSub takes pilot input only from its MAV_GCS_SYSID,
  # 255 by default).
  defp mavlink_ids!(vehicles, spec) do
    var = "NEPTUNUS_MAVLINK_IDS"

    configured =
      pairs!(var, spec, vehicles, "id=SYSTEM/COMPONENT pairs, e.g. sub=255/190")
      |> Map.new(fn {vehicle, pair, text} ->
        id = taking!(vehicle, :mavlink_ids, var, spec)

        with [system, component] <- String.split(text, "/"),
             {system, ""} when system in 1..255 <- Integer.parse(system),
             {component, ""} when component in 1..255 <- Integer.parse(component) do
          {id, {system, component}}
        else
          _ -> Config.bad!(var, spec, "SYSTEM/COMPONENT ids in 1..255 in #{inspect(pair)}")
        end
      end)

    Enum.map(vehicles, fn %{board: board, id: id} = vehicle ->
      if Board.takes?(board, :mavlink_ids) do
        {system, component} = Map.get(configured, id, {255, 190})
        Map.merge(vehicle, %{system: system, component: component})
      else
        vehicle
      end
    end)
  end

  # The delay (s) after a pilot loss before a mavlink vehicle is disarmed: `id=SECONDS`.
  defp mavlink_disarm_delay!(vehicles, spec) do
    var = "NEPTUNUS_MAVLINK_DISARM_DELAY"

    configured =
      pairs!(var, spec, vehicles, "id=SECONDS pairs, e.g. sub=2")
      |> Map.new(fn {vehicle, pair, text} ->
        id = taking!(vehicle, :disarm_delay, var, spec)

        case Float.parse(text) do
          {s, ""} when s >= 0.1 and s <= 60 -> {id, s}
          _ -> Config.bad!(var, spec, "a delay in seconds in 0.1..60 in #{inspect(pair)}")
        end
      end)

    put_configured(vehicles, configured, :disarm_delay)
  end

  # A SITL board that reboots into its bootloader whenever its line is opened, as a USB
  # Arduino does, losing what arrives for `id=MS` milliseconds (Board.OpenROV.SITL's `reset_on_open`
  # and `bootloader_ms`); without it the simulated board is up before the line opens.
  defp sitl_bootloader!(vehicles, spec) do
    var = "NEPTUNUS_SITL_BOOTLOADER"

    configured =
      pairs!(var, spec, vehicles, "id=MS pairs, e.g. rov=500")
      |> Map.new(fn {vehicle, pair, text} ->
        id = taking!(vehicle, :bootloader, var, spec)

        case Integer.parse(text) do
          {ms, ""} when ms in 1..10_000 -> {id, ms}
          _ -> Config.bad!(var, spec, "a bootloader time in ms in 1..10000 in #{inspect(pair)}")
        end
      end)

    Enum.map(vehicles, fn %{id: id} = vehicle ->
      case Map.fetch(configured, id) do
        {:ok, ms} -> Map.merge(vehicle, %{reset_on_open: true, bootloader_ms: ms})
        :error -> vehicle
      end
    end)
  end

  # the id of a vehicle whose board takes `setting` (Board.settings/0); refused otherwise,
  # naming the boards that do
  defp taking!(%{id: id, board: board}, setting, var, spec) do
    unless Board.takes?(board, setting) do
      boards = setting |> Board.taking() |> Enum.map(&Atom.to_string/1)
      Config.bad!(var, spec, "#{Config.alternatives(boards)} vehicles (#{id} is #{board})")
    end

    id
  end

  # each vehicle with a configured value (by id) gets it under `key`
  defp put_configured(vehicles, configured, key) do
    Enum.map(vehicles, fn %{id: id} = vehicle ->
      case Map.fetch(configured, id) do
        {:ok, value} -> Map.put(vehicle, key, value)
        :error -> vehicle
      end
    end)
  end

  # The `id=value` pairs of a per-vehicle variable as `{vehicle, pair, value}`; every id
  # must be a configured vehicle.
  defp pairs!(var, spec, vehicles, shape) do
    spec
    |> String.split(",", trim: true)
    |> Enum.map(&String.trim/1)
    |> Enum.reject(&(&1 == ""))
    |> Enum.map(fn pair ->
      case String.split(pair, "=", parts: 2) do
        [id, text] ->
          id = String.trim(id)

          case Enum.find(vehicles, &(&1.id == id)) do
            nil ->
              Config.bad!(var, spec, "ids of configured vehicles (no vehicle #{inspect(id)})")

            vehicle ->
              {vehicle, pair, String.trim(text)}
          end

        _ ->
          Config.bad!(var, spec, shape)
      end
    end)
  end

  defp vehicle!(pair, spec) do
    case String.split(pair, "=", parts: 2) do
      [id, board] ->
        id = String.trim(id)

        unless Regex.match?(~r/^[A-Za-z0-9_-]{1,32}$/, id) do
          Config.bad!(
            "NEPTUNUS_VEHICLES",
            spec,
            "vehicle ids of 1..32 characters a-z A-Z 0-9 _ - (got #{inspect(id)})"
          )
        end

        case Board.parse(String.trim(board)) do
          {:ok, board} ->
            Map.put(board, :id, id)

          {:error, expected, why} ->
            Config.bad!("NEPTUNUS_VEHICLES", spec, "#{expected} in #{inspect(pair)}: #{why}")
        end

      _ ->
        Config.bad!(
          "NEPTUNUS_VEHICLES",
          spec,
          "id=board pairs separated by commas, e.g. rov=simulated"
        )
    end
  end
end
