defmodule Neptunus.ConfigTest do
  use ExUnit.Case, async: true
  doctest Neptunus.Config
  doctest Neptunus.Config.Endpoint
  doctest Neptunus.Config.Vehicles
  doctest Neptunus.Config.Auth
  doctest Neptunus.Config.TLS
  doctest Neptunus.Config.Helm
  doctest Neptunus.Config.Recording
  doctest Neptunus.Config.OS
  doctest Neptunus.Config.Position

  alias Neptunus.Config

  describe "endpoint!/2" do
    test "defaults" do
      assert Config.Endpoint.endpoint!(%{}, 4102) == %{port: 4102, bind: {127, 0, 0, 1}}
    end

    test "IPv6 bind" do
      assert %{bind: {0, 0, 0, 0, 0, 0, 0, 1}} =
               Config.Endpoint.endpoint!(%{"NEPTUNUS_BIND" => "::1"}, 1)
    end

    for bad <- ["", "abc", "0", "65536", "80.5", "-1", "4000x"] do
      test "port #{inspect(bad)} is refused with the variable named" do
        assert_raise ArgumentError, ~r/NEPTUNUS_PORT=.*TCP port number/, fn ->
          Config.Endpoint.endpoint!(%{"NEPTUNUS_PORT" => unquote(bad)}, 4000)
        end
      end
    end

    test "bad bind address" do
      assert_raise ArgumentError, ~r/NEPTUNUS_BIND="localhost:80".*IP address/, fn ->
        Config.Endpoint.endpoint!(%{"NEPTUNUS_BIND" => "localhost:80"}, 4000)
      end
    end
  end

  describe "vehicles!/1" do
    test "default is one simulated vehicle" do
      assert [%{id: "neptunus-1", board: :simulated, camera: %{kind: :sim}}] =
               Config.Vehicles.vehicles!(%{})
    end

    test "several vehicles, whitespace tolerated" do
      assert [%{id: "a"}, %{id: "b_2"}] =
               Config.Vehicles.vehicles!(%{"NEPTUNUS_VEHICLES" => " a=simulated ,b_2= simulated"})
    end

    for {bad, message} <- [
          {"", ~r/at least one vehicle|id=board/},
          {"rov", ~r/id=board pairs/},
          {"rov=warp", ~r/known board.*simulated/},
          {"=simulated", ~r/vehicle ids/},
          {"a b=simulated", ~r/vehicle ids/},
          {"a=simulated,a=simulated", ~r/unique vehicle ids/},
          {String.duplicate("x", 33) <> "=simulated", ~r/vehicle ids/},
          {"a=simulated,", ~r/id=board pairs/}
        ] do
      test "refuses #{inspect(bad)}" do
        assert_raise ArgumentError, unquote(Macro.escape(message)), fn ->
          Config.Vehicles.vehicles!(%{"NEPTUNUS_VEHICLES" => unquote(bad)})
        end
      end
    end
  end

  describe "vehicles!/1 boards: sitl and uart, with wiring" do
    alias Neptunus.Vehicle.Board.OpenROV.Wiring

    test "sitl and uart vehicles get the thesis wiring and the openrov-2.5 firmware by default" do
      assert Config.Vehicles.vehicles!(%{
               "NEPTUNUS_VEHICLES" => "s=sitl,u=uart:/dev/ttyO1,m=simulated"
             })
             |> Enum.map(&Map.drop(&1, [:camera, :position])) ==
               [
                 %{id: "s", board: :sitl, wiring: Wiring.default(), firmware: :openrov_25},
                 %{
                   id: "u",
                   board: :uart,
                   device: "/dev/ttyO1",
                   baud: 115_200,
                   wiring: Wiring.default(),
                   firmware: :openrov_25
                 },
                 %{id: "m", board: :simulated}
               ]
    end

    test "baud rate and wiring as configured" do
      env = %{
        "NEPTUNUS_VEHICLES" => "a=uart:/dev/ttyUSB0@57600,b=sitl",
        "NEPTUNUS_WIRING" => " a=starboard/-vertical/port/ramp , b=port/vertical/starboard"
      }

      assert [%{baud: 57_600, wiring: wa}, %{wiring: wb}] = Config.Vehicles.vehicles!(env)
      assert Wiring.to_string(wa) == "starboard/-vertical/port/ramp"
      assert Wiring.to_string(wb) == "port/vertical/starboard/direct"
    end

    for {vehicles, wiring, message} <- [
          {"a=uart:ttyO1", "",
           ~r/uart:DEVICE\[@BAUD\] in "a=uart:ttyO1": the device must be an absolute path/},
          {"a=uart:/dev/ttyO1@115201", "", ~r/baud rate must be one of .*115200/},
          {"a=uart:/dev/ttyO1@fast", "", ~r/baud rate must be one of/},
          {"a=uart:/dev/tty@1@2", "", ~r/uart:DEVICE\[@BAUD\]/},
          {"a=uart", "", ~r/known board.*uart:DEVICE\[@BAUD\]/},
          {"a=sitl", "b=-port/vertical/starboard", ~r/NEPTUNUS_WIRING=.*no vehicle "b"/},
          {"a=simulated", "a=-port/vertical/starboard",
           ~r/sitl or uart vehicles \(a is simulated\)/},
          {"a=sitl", "a=port/port/starboard", ~r/exactly once/},
          {"a=sitl", "a", ~r/id=wiring pairs/}
        ] do
      test "refuses #{inspect(vehicles)} with wiring #{inspect(wiring)}" do
        assert_raise ArgumentError, unquote(Macro.escape(message)), fn ->
          Config.Vehicles.vehicles!(%{
            "NEPTUNUS_VEHICLES" => unquote(vehicles),
            "NEPTUNUS_WIRING" => unquote(wiring)
          })
        end
      end
    end
  end

  describe "vehicles!/1 firmware (NEPTUNUS_FIRMWARE)" do
    test "a firmware profile per sitl or uart vehicle" do
      env = %{
        "NEPTUNUS_VEHICLES" => "a=uart:/dev/ttyUSB0,b=sitl,c=sitl",
        "NEPTUNUS_FIRMWARE" => " a=openrov-30 , b=openrov-2.5"
      }

      assert [%{firmware: :openrov_30}, %{firmware: :openrov_25}, %{firmware: :openrov_25}] =
               Config.Vehicles.vehicles!(env)
    end

    for {vehicles, firmware, message} <- [
          {"a=sitl", "a=openrov-3",
           ~r/NEPTUNUS_FIRMWARE=.*openrov-2.5 or openrov-30, not "openrov-3"/},
          {"a=simulated", "a=openrov-30", ~r/NEPTUNUS_FIRMWARE=.*sitl or uart vehicles/},
          {"a=sitl", "b=openrov-30", ~r/NEPTUNUS_FIRMWARE=.*no vehicle "b"/},
          {"a=sitl", "openrov-30", ~r/NEPTUNUS_FIRMWARE=.*id=firmware pairs/}
        ] do
      test "refuses #{inspect(firmware)} for #{inspect(vehicles)}" do
        assert_raise ArgumentError, unquote(Macro.escape(message)), fn ->
          Config.Vehicles.vehicles!(%{
            "NEPTUNUS_VEHICLES" => unquote(vehicles),
            "NEPTUNUS_FIRMWARE" => unquote(firmware)
          })
        end
      end
    end
  end

  describe "vehicles!/1 SITL bootloader (NEPTUNUS_SITL_BOOTLOADER)" do
    test "a sitl vehicle reboots into a bootloader of that many ms whenever its line opens" do
      env = %{"NEPTUNUS_VEHICLES" => "a=sitl,b=sitl", "NEPTUNUS_SITL_BOOTLOADER" => " a=500 "}
      assert [a, b] = Config.Vehicles.vehicles!(env)
      assert %{reset_on_open: true, bootloader_ms: 500} = a
      refute Map.has_key?(b, :reset_on_open) or Map.has_key?(b, :bootloader_ms)
    end

    for {vehicles, bootloader, message} <- [
          {"a=simulated", "a=500", ~r/NEPTUNUS_SITL_BOOTLOADER=.*sitl vehicles/},
          {"a=sitl", "a=0", ~r/NEPTUNUS_SITL_BOOTLOADER=.*in 1..10000 in "a=0"/},
          {"a=sitl", "a=half", ~r/NEPTUNUS_SITL_BOOTLOADER=.*in 1..10000/},
          {"a=sitl", "a=20000", ~r/NEPTUNUS_SITL_BOOTLOADER=.*in 1..10000/},
          {"a=sitl", "b=500", ~r/NEPTUNUS_SITL_BOOTLOADER=.*no vehicle "b"/},
          {"a=sitl", "500", ~r/NEPTUNUS_SITL_BOOTLOADER=.*id=MS pairs/}
        ] do
      test "refuses #{inspect(bootloader)} for #{inspect(vehicles)}" do
        assert_raise ArgumentError, unquote(Macro.escape(message)), fn ->
          Config.Vehicles.vehicles!(%{
            "NEPTUNUS_VEHICLES" => unquote(vehicles),
            "NEPTUNUS_SITL_BOOTLOADER" => unquote(bootloader)
          })
        end
      end
    end
  end

  describe "vehicles!/1 position sources (NEPTUNUS_POSITION)" do
    defp positions(env) do
      %{"NEPTUNUS_VEHICLES" => "sim=simulated,rov=uart:/dev/ttyO1"}
      |> Map.merge(env)
      |> Config.Vehicles.vehicles!()
      |> Map.new(&{&1.id, &1.position})
    end

    test "simulated vehicles have the simulated DVL and USBL, others none, by default" do
      assert positions(%{}) == %{"sim" => [sim_dvl: [], sim_usbl: []], "rov" => []}
    end

    test "as configured, per vehicle; none turns them off" do
      assert %{"rov" => [{:dvl, "10.0.0.5", 16_171}, {:ugps, "http://10.0.0.6", r}], "sim" => []} =
               positions(%{
                 "NEPTUNUS_POSITION" => "rov=dvl:10.0.0.5+ugps:http://10.0.0.6/@-90, sim=none"
               })

      assert_in_delta r, -:math.pi() / 2, 1.0e-12
      assert %{"sim" => [sim_dvl: []]} = positions(%{"NEPTUNUS_POSITION" => "sim=sim-dvl"})
    end

    for {spec, message} <- [
          {"x=dvl:a", ~r/NEPTUNUS_POSITION=.*no vehicle "x"/},
          {"rov", ~r/id=sources pairs/},
          {"rov=sonar", ~r/a source is dvl:HOST\[:PORT\].*got "sonar"/},
          {"rov=dvl:", ~r/dvl needs HOST or HOST:PORT/},
          {"rov=dvl:a:99999", ~r/port must be in 1..65535/},
          {"rov=ugps:ftp://x", ~r/ugps needs an http:\/\/ URL/},
          {"rov=ugps:http://x@400", ~r/rotation must be in \[-360, 360\]/},
          {"rov=dvl:a+dvl:b", ~r/each kind of source once/},
          {"rov=sim-dvl", ~r/sim-dvl and sim-usbl on a simulated or sitl vehicle \(rov is uart\)/}
        ] do
      test "refuses #{inspect(spec)}" do
        assert_raise ArgumentError, unquote(Macro.escape(message)), fn ->
          positions(%{"NEPTUNUS_POSITION" => unquote(spec)})
        end
      end
    end
  end

  describe "vehicles!/1 models (NEPTUNUS_MODELS)" do
    test "names each vehicle's parameter set for its simulator and navigation filter" do
      env = %{
        "NEPTUNUS_VEHICLES" => "a=simulated,b=sitl,c=uart:/dev/ttyO1,d=simulated",
        "NEPTUNUS_MODELS" => " a=thesis-4dof, c=neptunus ,b=thesis-4dof"
      }

      assert [a, b, c, d] = Config.Vehicles.vehicles!(env)
      assert a.sim == [vehicle: "thesis-4dof"]
      assert b.sim == [vehicle: "thesis-4dof"]
      assert c.sim == [vehicle: "neptunus"]
      refute Map.has_key?(d, :sim)
    end

    for {models, message} <- [
          {"a=submarine",
           ~r/NEPTUNUS_MODELS=.*one of neptunus, neptunus-sway, thesis-4dof \(got "submarine"\)/},
          {"b=neptunus", ~r/NEPTUNUS_MODELS=.*no vehicle "b"/},
          {"a", ~r/id=model pairs, e.g. rov=thesis-4dof/},
          {"a=", ~r/got ""/}
        ] do
      test "refuses #{inspect(models)}" do
        assert_raise ArgumentError, unquote(Macro.escape(message)), fn ->
          Config.Vehicles.vehicles!(%{
            "NEPTUNUS_VEHICLES" => "a=simulated",
            "NEPTUNUS_MODELS" => unquote(models)
          })
        end
      end
    end
  end

  describe "recording!/2" do
    test "a directory (created later when missing), off, and the file size" do
      assert Config.Recording.recording!(%{"NEPTUNUS_RECORDINGS" => " /tmp/rec-x "}, "recordings") ==
               %{
                 dir: "/tmp/rec-x",
                 max_bytes: 256 * 1024 * 1024,
                 min_free_bytes: 512 * 1024 * 1024,
                 keep_ms: nil,
                 gap_ms: 600_000
               }

      assert Config.Recording.recording!(%{}, nil).dir == nil

      assert Config.Recording.recording!(%{"NEPTUNUS_RECORDING_MAX_MB" => "2"}, "r").max_bytes ==
               2 * 1024 * 1024
    end

    test "refuses a file, an empty value and a bad size" do
      assert_raise ArgumentError, ~r/NEPTUNUS_RECORDINGS=.*a directory \(this is a file\)/, fn ->
        Config.Recording.recording!(%{"NEPTUNUS_RECORDINGS" => "mix.exs"}, nil)
      end

      assert_raise ArgumentError, ~r/NEPTUNUS_RECORDINGS=.*a directory, or off/, fn ->
        Config.Recording.recording!(%{"NEPTUNUS_RECORDINGS" => " "}, nil)
      end

      for bad <- ["0", "65537", "big"] do
        assert_raise ArgumentError, ~r/NEPTUNUS_RECORDING_MAX_MB/, fn ->
          Config.Recording.recording!(%{"NEPTUNUS_RECORDING_MAX_MB" => bad}, nil)
        end
      end

      assert_raise ArgumentError, ~r/NEPTUNUS_RECORDING_MIN_FREE_MB/, fn ->
        Config.Recording.recording!(%{"NEPTUNUS_RECORDING_MIN_FREE_MB" => "-1"}, nil)
      end

      assert Config.Recording.recording!(%{"NEPTUNUS_RECORDING_MIN_FREE_MB" => "0"}, nil).min_free_bytes ==
               0
    end

    test "the helm's free time that ends a dive: minutes, 0 for never, or a clear error" do
      gap = &Config.Recording.recording!(%{"NEPTUNUS_DIVE_GAP_MIN" => &1}, nil).gap_ms
      assert gap.("1") == 60_000 and gap.("1440") == 1440 * 60_000 and gap.("0") == nil

      for bad <- ["-1", "1441", "ten"] do
        assert_raise ArgumentError, ~r/NEPTUNUS_DIVE_GAP_MIN/, fn -> gap.(bad) end
      end
    end

    test "retention: days, forever, or a clear error" do
      keep = &Config.Recording.recording!(%{"NEPTUNUS_RECORDING_KEEP_DAYS" => &1}, nil).keep_ms
      assert keep.(" 1 ") == 86_400_000
      assert keep.("3650") == 3650 * 86_400_000
      assert keep.("forever") == nil and keep.(" forever ") == nil

      for bad <- ["0", "3651", "-5", "7d", "", "never", "1.5"] do
        assert_raise ArgumentError,
                     ~r/NEPTUNUS_RECORDING_KEEP_DAYS=.* expected a number of days in 1..3650, or forever/,
                     fn -> keep.(bad) end
      end
    end
  end

  describe "os_time_slice_ns!/1 (NEPTUNUS_OS_SLICE_US)" do
    test "microseconds in 100..100000, default, or a clear error" do
      slice = &Config.OS.os_time_slice_ns!(%{"NEPTUNUS_OS_SLICE_US" => &1})
      assert Config.OS.os_time_slice_ns!(%{}) == 100_000
      assert slice.(" 100 ") == 100_000
      assert slice.("100000") == 100_000_000
      assert slice.("default") == nil and slice.(" default ") == nil

      for bad <- ["99", "100001", "0", "-100", "0.5", "1ms", "", "off"] do
        assert_raise ArgumentError,
                     ~r/NEPTUNUS_OS_SLICE_US=.* expected microseconds in 100..100000, or default/,
                     fn -> slice.(bad) end
      end
    end
  end

  describe "vehicles!/1 cameras (NEPTUNUS_CAMERAS)" do
    test "parses each vehicle's camera source" do
      env = %{
        "NEPTUNUS_VEHICLES" => "a=simulated,b=uart:/dev/ttyO1",
        "NEPTUNUS_CAMERAS" => "b=v4l2:/dev/video0@1280x720@30, a=testsrc"
      }

      assert [a, b] = Config.Vehicles.vehicles!(env)
      assert a.camera == %{kind: :testsrc, codec: :mjpeg, width: 640, height: 480, fps: 15}

      assert b.camera == %{
               kind: :v4l2,
               device: "/dev/video0",
               codec: :auto,
               width: 1280,
               height: 720,
               fps: 30
             }
    end

    test "simulated and SITL vehicles have the simulated camera unless told otherwise" do
      env = %{"NEPTUNUS_VEHICLES" => "a=simulated,b=sitl,c=uart:/dev/ttyO1,d=simulated"}
      [a, b, c, d] = Config.Vehicles.vehicles!(env)
      {:ok, sim} = Neptunus.Camera.Source.parse("sim")
      assert a.camera == sim and b.camera == sim and d.camera == sim
      refute Map.has_key?(c, :camera)

      [a, _, _, d] =
        Config.Vehicles.vehicles!(Map.put(env, "NEPTUNUS_CAMERAS", "a=none,d=sim@mjpeg"))

      refute Map.has_key?(a, :camera)
      assert d.camera.codec == :mjpeg
    end

    for {cameras, message} <- [
          {"a=webcam", ~r/NEPTUNUS_CAMERAS=.*a camera source: v4l2:DEVICE.* in "a=webcam"/},
          {"a=v4l2:/dev/video0@99", ~r/frame rate is 1..60/},
          {"z=testsrc", ~r/no vehicle "z"/},
          {"a", ~r/id=source pairs/}
        ] do
      test "refuses #{inspect(cameras)}" do
        assert_raise ArgumentError, unquote(Macro.escape(message)), fn ->
          Config.Vehicles.vehicles!(%{
            "NEPTUNUS_VEHICLES" => "a=simulated",
            "NEPTUNUS_CAMERAS" => unquote(cameras)
          })
        end
      end
    end
  end

  describe "max_connections!/1" do
    test "unset: nil (derived from the descriptor limit at boot)" do
      assert Config.Endpoint.max_connections!(%{}) == nil
    end

    test "a count, whitespace tolerated" do
      assert Config.Endpoint.max_connections!(%{"NEPTUNUS_MAX_CONNECTIONS" => " 2000 "}) == 2000
      assert Config.Endpoint.max_connections!(%{"NEPTUNUS_MAX_CONNECTIONS" => "1"}) == 1

      assert Config.Endpoint.max_connections!(%{"NEPTUNUS_MAX_CONNECTIONS" => "1048576"}) ==
               1_048_576
    end

    for bad <- ["0", "-5", "1048577", "many", "", "10.5", "1e3"] do
      test "refuses #{inspect(bad)} with the variable named" do
        error =
          assert_raise ArgumentError, fn ->
            Config.Endpoint.max_connections!(%{"NEPTUNUS_MAX_CONNECTIONS" => unquote(bad)})
          end

        assert error.message =~ "NEPTUNUS_MAX_CONNECTIONS=#{inspect(unquote(bad))} is not valid"
        assert error.message =~ "1..1048576"
      end
    end
  end
end
