defmodule Neptunus.ReleaseArmhfTest do
  # The armhf tarball of `make release-armhf`, booted on this x86 machine under qemu-user
  # against the board's Debian packages unpacked in _build/armhf/sysroot: every native object
  # is 32-bit ARM, the node starts, answers /api/health, a `sitl` vehicle is driven by a pilot's
  # thrust over the WebSocket through the armhf port program, and the node stops cleanly.
  # Slow (everything ARM is emulated): `make test-target` runs it after building the tarball.
  use ExUnit.Case, async: false

  import Neptunus.Test.Vehicles, only: [free_port: 0]

  alias Neptunus.Test.ReleaseRig

  @moduletag :target
  @moduletag :external
  @moduletag timeout: 900_000

  @root Path.expand("..", __DIR__)
  @build Path.join(@root, "_build/armhf")
  @vehicle "rov"

  setup_all do
    version = Mix.Project.config()[:version]
    tarball = Path.join(@build, "neptunus-#{version}-armhf.tar.gz")
    assert File.exists?(tarball), "#{tarball} is missing: run make release-armhf"

    dir =
      Path.join(System.tmp_dir!(), "neptunus-armhf-test-#{System.unique_integer([:positive])}")

    rel = Path.join(dir, "rel")
    File.mkdir_p!(rel)
    {_, 0} = System.cmd("tar", ["-C", rel, "-xzf", tarball])
    on_exit(fn -> File.rm_rf!(dir) end)
    %{dir: dir, rel: rel, version: version}
  end

  test "every native object in the tarball is 32-bit ARM, EABI5 (hard float)", %{rel: rel} do
    objects = ReleaseRig.elf_files(rel)
    names = Enum.map(objects, &Path.basename/1)

    for name <- ~w(beam.smp erlexec erl_child_setup epmd neptunus_uart neptunus_camera
                   neptunus_dynamics_nif.so
                   neptunus_os_nif.so crypto.so jiffy.so) do
      assert name in names, "#{name} is not in the tarball"
    end

    not_arm =
      for path <- objects,
          {description, 0} = System.cmd("file", ["-b", path]),
          not (description =~ "ELF 32-bit LSB" and description =~ "ARM, EABI5"),
          do: {Path.relative_to(path, rel), String.trim(description)}

    assert not_arm == []

    # what the board must provide, and nothing of this machine's
    packages = rel |> Path.join("etc/debian-packages") |> File.read!() |> String.split()
    assert "libc6" in packages and "libssl3" in packages and "libtinfo6" in packages
    assert File.read!(Path.join(rel, "etc/architecture")) == "armhf\n"
    assert File.exists?(Path.join(rel, "bin/neptunus-install"))
  end

  test "boots under qemu-user, drives a sitl vehicle through the armhf port program, stops",
       %{dir: dir, rel: rel} do
    :ok = ReleaseRig.register_qemu_arm!()
    # a host epmd, so that no emulated one outlives the test
    {_, 0} = System.cmd("epmd", ["-daemon"])

    port = free_port()
    bin = Path.join(rel, "bin/neptunus")

    env = [
      {"QEMU_LD_PREFIX", Path.join(@build, "sysroot")},
      {"NEPTUNUS_PORT", "#{port}"},
      {"NEPTUNUS_VEHICLES", "#{@vehicle}=sitl"},
      {"NEPTUNUS_RECORDINGS", Path.join(dir, "recordings")},
      {"RELEASE_NODE", "neptunus_armhf_test_#{port}"},
      {"RELEASE_TMP", dir}
    ]

    node =
      Port.open({:spawn_executable, bin}, [
        :binary,
        :exit_status,
        :stderr_to_stdout,
        args: ["start"],
        env: Enum.map(env, fn {k, v} -> {String.to_charlist(k), String.to_charlist(v)} end)
      ])

    try do
      health = ReleaseRig.until_healthy(port, 300_000)
      assert %{"status" => "ok", "vehicles" => [%{"id" => @vehicle, "board" => "sitl"}]} = health

      info =
        ReleaseRig.rpc!(
          rel,
          """
          IO.write(inspect({:erlang.system_info(:system_architecture),
            Neptunus.Vehicle.Board.OpenROV.UART.program(), Neptunus.Dynamics.Native.available?()}))
          """,
          env
        )

      {arch, program, nif?} = info |> Code.eval_string() |> elem(0)
      assert to_string(arch) =~ ~r/^arm.*linux-gnueabihf$/
      assert nif?
      # the port program the board link runs is the release's, an ARM one
      assert String.starts_with?(Path.expand(program), Path.expand(rel))

      {description, 0} = System.cmd("file", ["-bL", program])
      assert description =~ "ARM, EABI5"

      # the board link is up: the simulated board answers through the pty and the port program
      watch_link = """
      IO.write(Enum.find_value(1..600, false, fn _ ->
        Neptunus.Vehicle.Board.link_status("#{@vehicle}").up ||
          (Process.sleep(100); nil)
      end))
      """

      assert ReleaseRig.rpc!(rel, watch_link, env) == "true"

      # a pilot's thrust over the WebSocket reaches the simulated board as ESC pulses
      pilot = ReleaseRig.pilot!(port, @vehicle)

      watch_board = """
      IO.write(inspect(Enum.find_value(1..600, :neutral, fn _ ->
        case Neptunus.Vehicle.Board.OpenROV.SITL.Device.state("#{@vehicle}").firmware.target_us do
          {1500, 1500, 1500} -> Process.sleep(50); nil
          pulses -> pulses
        end
      end)))
      """

      watcher = Task.async(fn -> ReleaseRig.rpc!(rel, watch_board, env) end)
      pulses = keep_thrusting(pilot, watcher)
      assert pulses =~ ~r/^\{\d+, \d+, \d+\}$/, "no thrust reached the board: #{pulses}"
    after
      System.cmd(bin, ["stop"], env: env, stderr_to_stdout: true)
    end

    assert_receive {^node, {:exit_status, 0}}, 120_000
    assert ReleaseRig.get(port, "/api/health") == :down
    # a clean boot: nothing at error level until it serves (yaws' include files are in the
    # release)
    assert [boot, _] = node |> output("") |> String.split("serving http://127.0.0.1:#{port}")
    refute boot =~ "[error]"
  end

  defp output(node, acc) do
    receive do
      {^node, {:data, data}} -> output(node, acc <> data)
    after
      0 -> acc
    end
  end

  # thrust and heartbeat every 100 ms until the watcher in the node reports what the board got
  defp keep_thrusting(pilot, watcher) do
    ReleaseRig.thrust(pilot, 0.5)

    case Task.yield(watcher, 100) do
      {:ok, result} -> result
      nil -> keep_thrusting(pilot, watcher)
    end
  end
end
