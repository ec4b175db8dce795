defmodule Neptunus.InstallTest do
  # rel/neptunus-install, the script shipped in every release tarball (bin/neptunus-install),
  # run on this machine under a temporary root (`--root`).
  #
  # Quick (make test): bad usage and bad tarballs change nothing; the systemd unit and the
  # settings template are installed and the service restarted through systemctl (a fake one on
  # PATH that records its calls, beside a fake release that never becomes healthy).
  #
  # Slow (:target, make test-target): two releases built from this tree, the second made
  # unable to become healthy (its vehicle's board link never comes up), started directly
  # (`--no-systemd`): the first installs and runs; an update is refused while someone pilots;
  # then the update to the second is rolled back and the first runs again.
  use ExUnit.Case, async: true

  import Neptunus.Test.Vehicles, only: [free_port: 0]

  alias Neptunus.Test.ReleaseRig

  @root Path.expand("..", __DIR__)
  @script Path.join(@root, "rel/neptunus-install")

  defp install(args, env \\ []) do
    System.cmd("bash", [@script | args], stderr_to_stdout: true, env: env)
  end

  defp tar!(dir, tarball) do
    {_, 0} = System.cmd("tar", ["-C", dir, "-czf", tarball, "."])
    tarball
  end

  describe "bad input" do
    @describetag :tmp_dir

    test "unknown options, no tarball, a bad timeout: exit 2, nothing installed", %{tmp_dir: dir} do
      assert {out, 2} = install(["--root", dir, "--frobnicate", "x.tar.gz"])
      assert out =~ "unknown option --frobnicate"
      assert {out, 2} = install(["--root", dir])
      assert out =~ "no tarball given"
      assert {out, 2} = install(["--root", dir, Path.join(dir, "missing.tar.gz")])
      assert out =~ "no such file"
      File.write!(Path.join(dir, "t.tar.gz"), "")
      assert {out, 2} = install(["--root", dir, "--timeout", "soon", Path.join(dir, "t.tar.gz")])
      assert out =~ "--timeout must be whole seconds"
      assert File.ls!(dir) == ["t.tar.gz"]
    end

    test "a tarball that is not a release: exit 2, no release, no current link", %{tmp_dir: dir} do
      junk = Path.join(dir, "junk")
      File.mkdir_p!(junk)
      File.write!(Path.join(junk, "README"), "not a release")
      tarball = tar!(junk, Path.join(dir, "junk.tar.gz"))
      root = Path.join(dir, "root")
      File.mkdir_p!(root)

      assert {out, 2} = install(["--root", root, "--no-systemd", tarball])
      assert out =~ "is not a Neptunus release"
      assert File.ls!(Path.join(root, "opt/neptunus/releases")) == []
      refute File.exists?(Path.join(root, "opt/neptunus/current"))
    end

    test "a release for another architecture is refused", %{tmp_dir: dir} do
      release = fake_release(dir, "9.9.9")
      other = if :erlang.system_info(:wordsize) == 8, do: "armhf", else: "amd64"
      File.write!(Path.join(release, "etc/architecture"), other <> "\n")
      tarball = tar!(release, Path.join(dir, "other.tar.gz"))
      root = Path.join(dir, "root")
      File.mkdir_p!(root)

      assert {out, 2} = install(["--root", root, "--no-systemd", tarball])
      assert out =~ "is for #{other}"
      refute File.exists?(Path.join(root, "opt/neptunus/current"))
    end
  end

  describe "systemd" do
    @describetag :tmp_dir

    test "installs the unit and the settings, restarts through systemctl, reports unhealthy",
         %{tmp_dir: dir} do
      tarball = tar!(fake_release(dir, "9.9.9"), Path.join(dir, "fake.tar.gz"))
      root = Path.join(dir, "root")
      File.mkdir_p!(root)

      {calls, env} = recording_systemctl(dir)

      assert {out, 1} = install(["--root", root, "--no-user", "--timeout", "1", tarball], env)
      assert out =~ "did not become healthy within 1s"
      assert out =~ "no previous release to go back to"

      assert File.read!(calls) == "daemon-reload\nenable neptunus\nrestart neptunus\n"
      current = Path.join(root, "opt/neptunus/current")
      assert File.read_link!(current) == "releases/9.9.9"

      unit = File.read!(Path.join(root, "etc/systemd/system/neptunus.service"))
      assert unit =~ "ExecStart=#{current}/bin/neptunus start\n"
      assert unit =~ "ExecStop=#{current}/bin/neptunus stop\n"
      assert unit =~ "EnvironmentFile=#{root}/etc/neptunus.env\n"
      assert unit =~ "WorkingDirectory=#{root}/var/lib/neptunus\n"

      # the settings template, installed once and never overwritten
      settings = Path.join(root, "etc/neptunus.env")
      assert File.read!(settings) == File.read!(Path.join(@root, "rel/neptunus.env"))
      File.write!(settings, "NEPTUNUS_PORT=#{free_port()}\n")
      tarball2 = tar!(fake_release(dir, "9.9.10"), Path.join(dir, "fake2.tar.gz"))
      assert {_, 1} = install(["--root", root, "--no-user", "--timeout", "1", tarball2], env)
      assert File.read!(settings) =~ "NEPTUNUS_PORT="
      refute File.read!(settings) =~ "NEPTUNUS_VEHICLES"
      # both releases side by side; the unhealthy second one rolled back to the first
      assert File.ls!(Path.join(root, "opt/neptunus/releases")) |> Enum.sort() == ~w(9.9.10 9.9.9)
      assert File.read_link!(current) == "releases/9.9.9"
    end
  end

  describe "checks of the running node and --no-start (the firmware image uses them)" do
    @describetag :tmp_dir

    test "no node answering: the helm is free, the node is not healthy", %{tmp_dir: dir} do
      File.mkdir_p!(Path.join(dir, "etc"))
      File.write!(Path.join(dir, "etc/neptunus.env"), "NEPTUNUS_PORT=#{free_port()}\n")
      assert {out, 0} = install(["--root", dir, "--check-helm"])
      assert out =~ "no node answers; the helm is free"
      assert {out, 1} = install(["--root", dir, "--check-healthy", "--timeout", "1"])
      assert out =~ "the node is not healthy after 1s (/api/health: no answer)"
      assert {out, 2} = install(["--root", dir, "--check-helm", "x.tar.gz"])
      assert out =~ "--check-helm takes no tarball"
    end

    test "--no-start installs the release, the unit and the settings, and starts nothing",
         %{tmp_dir: dir} do
      tarball = tar!(fake_release(dir, "9.9.9"), Path.join(dir, "fake.tar.gz"))
      root = Path.join(dir, "root")
      File.mkdir_p!(root)
      {calls, env} = recording_systemctl(dir)

      assert {out, 0} = install(["--root", root, "--no-user", "--no-start", tarball], env)
      assert out =~ "installed neptunus 9.9.9 (not started: --no-start)"
      assert File.read_link!(Path.join(root, "opt/neptunus/current")) == "releases/9.9.9"
      assert File.exists?(Path.join(root, "etc/systemd/system/neptunus.service"))
      assert File.exists?(Path.join(root, "etc/neptunus.env"))
      refute File.exists?(calls)
    end
  end

  # A systemctl on PATH that records its calls: the file of calls, the environment to use.
  defp recording_systemctl(dir) do
    bin = Path.join(dir, "bin")
    File.mkdir_p!(bin)
    calls = Path.join(dir, "systemctl.calls")
    File.write!(Path.join(bin, "systemctl"), "#!/bin/sh\necho \"$*\" >> #{calls}\n")
    File.chmod!(Path.join(bin, "systemctl"), 0o755)
    {calls, [{"PATH", bin <> ":" <> System.get_env("PATH")}]}
  end

  # A release that never becomes healthy: the layout neptunus-install looks for, a bin/neptunus
  # that fails every command.
  defp fake_release(dir, version) do
    release = Path.join(dir, "fake-#{version}")
    File.mkdir_p!(Path.join(release, "bin"))
    File.mkdir_p!(Path.join(release, "etc"))
    File.mkdir_p!(Path.join(release, "releases/#{version}"))
    File.write!(Path.join(release, "releases/start_erl.data"), "13.1.5 #{version}\n")
    File.write!(Path.join(release, "bin/neptunus"), "#!/bin/sh\nexit 1\n")
    File.chmod!(Path.join(release, "bin/neptunus"), 0o755)
    File.cp!(Path.join(@root, "rel/neptunus.service"), Path.join(release, "etc/neptunus.service"))
    File.cp!(Path.join(@root, "rel/neptunus.env"), Path.join(release, "etc/neptunus.env"))
    release
  end

  describe "update and rollback of real releases" do
    @describetag :target
    @describetag :external
    @describetag :tmp_dir
    @describetag timeout: 900_000

    test "installs, refuses while piloted, rolls an unhealthy update back", %{tmp_dir: dir} do
      v1 = build_release!(dir, "0.1.0", nil)
      # the second release's vehicle is on a serial device that does not exist: the node
      # answers /api/health but its board link never comes up
      v2 = build_release!(dir, "0.1.1", "export NEPTUNUS_VEHICLES=rov=uart:/nonexistent/tty\n")

      root = Path.join(dir, "root")
      File.mkdir_p!(Path.join(root, "etc"))
      port = free_port()
      node = "neptunus_install_test_#{port}"

      File.write!(Path.join(root, "etc/neptunus.env"), """
      NEPTUNUS_BIND=127.0.0.1
      NEPTUNUS_PORT=#{port}
      NEPTUNUS_VEHICLES=rov=sitl
      NEPTUNUS_RECORDINGS=recordings
      RELEASE_NODE=#{node}
      """)

      current = Path.join(root, "opt/neptunus/current")
      rpc_env = [{"RELEASE_NODE", node}]

      try do
        assert {out, 0} = install(["--root", root, "--no-systemd", "--timeout", "120", v1])
        assert out =~ "neptunus 0.1.0 is running and healthy"
        assert File.read_link!(current) == "releases/0.1.0"
        assert %{"status" => "ok"} = ReleaseRig.until_healthy(port, 10_000)

        # someone pilots: the update is refused and nothing changes
        pilot = ReleaseRig.pilot!(port, "rov")
        assert {out, 3} = install(["--root", root, "--no-systemd", "--timeout", "60", v2])
        assert out =~ "not updating while someone pilots: rov (piloted)"
        assert File.read_link!(current) == "releases/0.1.0"
        refute File.exists?(Path.join(root, "opt/neptunus/releases/0.1.1"))

        # with --wait it waits for the helm; the pilot leaves; the update starts 0.1.1, which
        # never becomes healthy
        updater =
          Port.open({:spawn_executable, System.find_executable("bash")}, [
            :binary,
            :exit_status,
            :stderr_to_stdout,
            args: [@script, "--root", root, "--no-systemd", "--wait", "--timeout", "20", v2]
          ])

        waiting = port_output(updater, "", "waiting for a free helm: rov (piloted)")
        assert File.read_link!(current) == "releases/0.1.0"
        refute File.exists?(Path.join(root, "opt/neptunus/releases/0.1.1"))
        {ws, _, _, _} = pilot
        NeptunusWeb.Test.WSClient.close(ws)
        {out, 1} = port_exit(updater, waiting)
        assert out =~ "starting neptunus 0.1.1 (was 0.1.0)"
        assert out =~ "neptunus 0.1.1 did not become healthy within 20s"
        assert out =~ "rolled back to neptunus 0.1.0"
        assert out =~ "neptunus 0.1.0 is running and healthy again"
        assert File.read_link!(current) == "releases/0.1.0"
        assert File.dir?(Path.join(root, "opt/neptunus/releases/0.1.1"))
        assert %{"status" => "ok"} = ReleaseRig.until_healthy(port, 10_000)

        assert ReleaseRig.rpc!(current, ~s|IO.write(System.get_env("RELEASE_VSN"))|, rpc_env) ==
                 "0.1.0"
      after
        if File.exists?(current) do
          System.cmd(Path.join(current, "bin/neptunus"), ["stop"],
            env: rpc_env,
            stderr_to_stdout: true
          )
        end
      end
    end
  end

  # the output of the install script's port until it contains `line` (or the script exits)
  defp port_output(port, acc, line) do
    if acc =~ line do
      acc
    else
      receive do
        {^port, {:data, data}} ->
          port_output(port, acc <> data, line)

        {^port, {:exit_status, status}} ->
          flunk("exit #{status} before #{inspect(line)}:\n#{acc}")
      after
        120_000 -> flunk("no #{inspect(line)} within 120 s:\n#{acc}")
      end
    end
  end

  defp port_exit(port, acc) do
    receive do
      {^port, {:data, data}} -> port_exit(port, acc <> data)
      {^port, {:exit_status, status}} -> {acc, status}
    after
      180_000 -> flunk("the install script did not finish:\n#{acc}")
    end
  end

  # `mix release` of this tree as release version `version` (MIX_ENV=prod), with `env_sh`
  # appended to its env.sh; the tarball.
  defp build_release!(dir, version, env_sh) do
    path = Path.join(dir, "rel-#{version}")

    {output, status} =
      System.cmd("mix", ["release", "--overwrite", "--quiet", "--path", path],
        cd: @root,
        env: [
          {"MIX_ENV", "prod"},
          {"MIX_BUILD_PATH", nil},
          {"NEPTUNUS_RELEASE_VERSION", version}
        ],
        stderr_to_stdout: true
      )

    assert status == 0, "mix release failed:\n#{output}"

    if env_sh do
      File.write!(Path.join(path, "releases/#{version}/env.sh"), env_sh, [:append])
    end

    tar!(path, Path.join(dir, "neptunus-#{version}.tar.gz"))
  end
end
