defmodule Neptunus.FirmwareTest do
  # The SD-card image of `make firmware`, booted under full-system emulation: qemu-system-arm's
  # `virt` machine (one core, 512 MB, as the BeagleBone) with Debian's u-boot-qemu, booting
  # the same card (boot partition, root A/B, data) through the same A/B boot script and state
  # file as the board. The network is qemu's user network, forwarded to loopback: the card's
  # HTTPS (443) and SSH (22). The BeagleBone's own first stage (MLO, u-boot.img) is checked by
  # inspecting the boot partition, since qemu does not emulate the AM335x.
  #
  # One story, in order (each step's time printed): first boot (keys, password, name); a dive
  # through the phoenix JS client; truncated, corrupted and unsigned updates refused with
  # nothing written; an update refused while a pilot holds the helm; an update written to
  # slot B, booted once and marked good; power lost while writing the next update (qemu
  # killed), the old firmware boots; an update whose Neptunus cannot start, the automatic
  # fall back to the good slot, the rollback and its reason recorded, the data intact.
  # `make test-firmware` builds the image and runs it (`mix test --only firmware`).
  use ExUnit.Case, async: false

  import Neptunus.Test.Vehicles, only: [free_port: 0]

  @moduletag :firmware
  @moduletag :external
  @moduletag timeout: 3_600_000

  @root Path.expand("..", __DIR__)
  @build Path.join(@root, "_build/firmware")
  @uboot "/usr/lib/u-boot/qemu_arm/u-boot.bin"
  @mib 1024 * 1024
  # the card's layout (rel/firmware/build): boot at 1 MiB, 32 MiB; slots of 512 MiB
  @boot_offset 1 * @mib
  @slot_a_offset 33 * @mib
  @slot_b_offset (33 + 512) * @mib
  # a boot under TCG on a busy 2-core machine: generous, the test waits on the events
  @boot_ms 1_800_000

  setup_all do
    version = Mix.Project.config()[:version]
    name = "neptunus-#{version}-beaglebone"
    image = Path.join(@build, name <> ".img.xz")
    update = Path.join(@build, name <> ".fw")
    root_img = Path.join(@build, "root.ext4")

    for file <- [image, update, root_img],
        do: assert(File.exists?(file), "#{file} is missing: run make firmware")

    assert File.exists?(@uboot), "#{@uboot} is missing: run make setup-firmware"

    dir =
      Path.join(System.tmp_dir!(), "neptunus-firmware-test-#{System.unique_integer([:positive])}")

    File.mkdir_p!(dir)
    on_exit(fn -> File.rm_rf!(dir) end)

    disk = Path.join(dir, "card.img")

    {_, 0} =
      System.cmd("bash", ["-c", "xz -dc '#{image}' | cp --sparse=always /dev/stdin '#{disk}'"])

    # a 2 GB card: the first boot grows the data partition to its end
    {_, 0} = System.cmd("truncate", ["-s", "2G", disk])

    %{dir: dir, disk: disk, root_img: root_img, version: version}
  end

  test "the boot partition carries the BeagleBone's first stage, U-Boot and the A/B script",
       %{version: version} do
    # the card as built (the other test boots and updates its own copy)
    disk = Path.join(@build, "neptunus-#{version}-beaglebone.img")
    assert File.exists?(disk), "#{disk} is missing: run make firmware"

    {table, 0} = System.cmd("sfdisk", ["--dump", disk])
    [p1 | _] = parts = Regex.scan(~r/^\S+ : (.*)$/m, table, capture: :all_but_first)
    assert length(parts) == 4
    # the AM335x boot ROM reads MLO from the active FAT partition
    assert hd(p1) =~ "type=e" and hd(p1) =~ "bootable"

    {listing, 0} = System.cmd("mdir", ["-b", "-i", "#{disk}@@#{@boot_offset}", "::"])
    files = listing |> String.split("\n", trim: true) |> Enum.map(&Path.basename/1)
    # MLO first in the directory (the ROM takes the first match), then U-Boot, the script
    assert ["MLO", "u-boot.img" | _] = Enum.map(files, &String.trim/1)
    assert "boot.scr" in files and "neptunus-boot.txt" in files

    mlo = boot_file!(disk, "MLO")
    # an AM335x first stage for an SD card: the ROM's 512-byte table of contents (its
    # CHSETTINGS item), then the GP header: the image's size and its load address in the
    # internal RAM
    assert binary_part(mlo, 0x14, 10) == "CHSETTINGS"
    <<_toc::binary-size(512), size::little-32, load::little-32, _::binary>> = mlo
    assert load == 0x402F0400
    assert size > 0 and size <= byte_size(mlo) - 512
    # U-Boot proper: a FIT image (or a legacy one)
    assert <<magic::big-32, _::binary>> = boot_file!(disk, "u-boot.img")
    assert magic in [0xD00DFEED, 0x27051956]
    # the A/B script, compiled with mkimage
    assert <<0x27, 0x05, 0x19, 0x56, _::binary>> = script = boot_file!(disk, "boot.scr")
    assert script =~ "neptunus-boot.txt" and script =~ "fatwrite"
    assert boot_file!(disk, "neptunus-boot.txt") == "nep_slot=A\n"
  end

  test "first boot, a dive, updates refused, an update kept, power lost, an update rolled back",
       %{dir: dir, disk: disk, root_img: root_img, version: version} do
    key = Path.join(dir, "id_ed25519")
    {_, 0} = System.cmd("ssh-keygen", ["-q", "-t", "ed25519", "-N", "", "-f", key])

    # what a user puts on the card from a PC before the first boot: an SSH key, and a SITL
    # vehicle (the simulated board behind the ARM port program) instead of the real UART's
    put_boot_file!(disk, "authorized_keys", File.read!(key <> ".pub"))
    put_boot_file!(disk, "neptunus.env", "NEPTUNUS_VEHICLES=rov=sitl\n")

    vm = %{
      dir: dir,
      disk: disk,
      key: key,
      https: free_port(),
      ssh: free_port(),
      console: Path.join(dir, "console.log")
    }

    # --- 1. first boot ----------------------------------------------------------------------
    {qemu, first_boot_ms} = timed("first boot to /api/health", fn -> boot!(vm) end)

    health = health!(vm)
    assert %{"status" => "ok", "vehicles" => [%{"id" => "rov", "board" => "sitl"}]} = health

    password_file = boot_file!(disk, "neptunus-admin-password.txt")
    [_, password] = Regex.run(~r/password: (\S+)/, password_file)
    assert console_text(vm) =~ "the admin's first password is #{password}"
    assert ssh!(vm, "hostname") =~ ~r/^neptunus-[0-9a-f]{6}$/
    assert ssh!(vm, "findmnt -no OPTIONS /") =~ ~r/(^|,)ro(,|$)/
    assert ssh!(vm, "neptunus-firmware status") =~ "running: slot A, firmware #{version}"
    assert String.to_integer(String.trim(ssh!(vm, "df -m --output=size /data | tail -n1"))) > 800
    # SSH takes keys only
    {out, status} =
      System.cmd("ssh", ssh_args(vm, ["-o", "PubkeyAuthentication=no"]) ++ ["true"],
        stderr_to_stdout: true
      )

    assert status != 0 and out =~ "Permission denied"
    boot_applied = boot_listing(disk)
    assert "authorized_keys.applied" in boot_applied and "neptunus.env.applied" in boot_applied

    cert = cert_fingerprint(vm)
    # an update has 300 s to become healthy on a board; the emulated one on a loaded build
    # machine needed more than that to start Neptunus after a reboot (a kept update was
    # judged unhealthy and rolled back): give it 20 min (the broken update gets 60 s below)
    ssh!(vm, "echo 1200 > /data/etc/firmware-health-timeout")
    ssh!(vm, "echo 'from the first firmware' > /data/neptunus/marker")

    # --- 2. a dive through the phoenix JS client --------------------------------------------
    timed("a dive through the phoenix client", fn -> dive!(vm, password) end)

    {{rss_kib, _}, _} =
      timed("idle memory", fn ->
        ssh!(vm, "awk '/MemTotal/ {t=$2} /MemAvailable/ {a=$2} END {print t-a}' /proc/meminfo")
        |> Integer.parse()
      end)

    beam_kib = ssh!(vm, "ps -C beam.smp -o rss= | awk '{s+=$1} END {print s}'") |> String.trim()

    IO.puts(
      "[firmware] idle memory in use (MemTotal - MemAvailable): #{div(rss_kib, 1024)} MiB " <>
        "of #{ssh!(vm, "awk '/MemTotal/ {print int($2/1024)}' /proc/meminfo") |> String.trim()} MiB; " <>
        "the BEAM's RSS #{div(String.to_integer(beam_kib), 1024)} MiB"
    )

    # --- 3. bad updates: refused, nothing written -------------------------------------------
    # small ones (the checks do not depend on the size; the emulated board moves ~1 MB/s):
    # a root of 2 MiB of noise, signed with the build's key, then damaged in each way
    small = small_update!(dir, "#{version}+small", nil)
    slot_b = slot_digest(disk, @slot_b_offset)

    timed("truncated, corrupted, unsigned updates refused", fn ->
      size = File.stat!(small).size
      truncated = Path.join(dir, "truncated.fw")
      File.write!(truncated, binary_part(File.read!(small), 0, div(size, 2)))
      {out, 2} = upload(vm, truncated)
      assert out =~ "truncated"

      corrupted = Path.join(dir, "corrupted.fw")
      File.cp!(small, corrupted)
      # a byte in the middle of the compressed root (the bulk of the file)
      flip_byte!(corrupted, div(size, 2))
      {out, 2} = upload(vm, corrupted)
      assert out =~ "damaged"

      # signed by another key than the one the image was built with
      other_key = Path.join(dir, "other-key.pem")
      {_, 0} = System.cmd("openssl", ["genpkey", "-algorithm", "ed25519", "-out", other_key])
      {out, 2} = upload(vm, small_update!(dir, "#{version}+unsigned", other_key))
      assert out =~ "signature does not match"
    end)

    assert slot_digest(disk, @slot_b_offset) == slot_b
    assert boot_file!(disk, "neptunus-boot.txt") == "nep_slot=A\n"

    # --- 4. never while a pilot holds the helm ----------------------------------------------
    timed("an update refused while a pilot holds the helm", fn ->
      pilot = hold_helm!(vm, password)

      try do
        {out, 3} = upload(vm, small)
        assert out =~ "not updating while someone pilots: rov"
      after
        Port.close(pilot)
      end
    end)

    assert slot_digest(disk, @slot_b_offset) == slot_b

    # --- 5. an update: slot B, booted once, marked good -------------------------------------
    good = variant!(dir, root_img, "#{version}+test.2", [])
    {{out, 0}, _} = timed("the update sent and written to slot B", fn -> upload(vm, good) end)
    assert out =~ "slot B holds firmware #{version}+test.2"
    wait_exit!(qemu, vm)

    {qemu, second_boot_ms} =
      timed("reboot into slot B to /api/health", fn -> boot!(vm, reboot: qemu) end)

    timed("slot B marked good", fn -> until_marked!(vm, "good slot: B") end)
    assert ssh!(vm, "cat /etc/neptunus/firmware-version") == "#{version}+test.2\n"
    assert ssh!(vm, "neptunus-firmware status") =~ "result=updated"
    assert %{"firmware_update" => %{"result" => "updated"}} = health!(vm)
    assert_data_intact!(vm, cert, password)

    # --- 6. power lost while writing the next update ----------------------------------------
    # (the next update, whose Neptunus cannot start, sent once and kept on the data partition)
    broken =
      variant!(dir, root_img, "#{version}+broken", [{"bin/neptunus", "#!/bin/sh\nexit 1\n"}])

    timed("the broken update sent to /data", fn -> ssh!(vm, "cat > /data/broken.fw", broken) end)
    slot_a = slot_digest(disk, @slot_a_offset)

    timed("power lost while writing slot A", fn ->
      updater = ssh_port(vm, "neptunus-firmware update /data/broken.fw")
      # the first MiB of slot A changes: the write has begun; the power goes at once
      until!(600_000, "the write to slot A to begin", fn ->
        slot_digest(disk, @slot_a_offset) != slot_a
      end)

      kill!(qemu)

      # its connection went with the board
      receive do
        {^updater, {:exit_status, _}} -> :ok
      after
        60_000 -> flunk("the update's ssh did not end with the board")
      end
    end)

    assert boot_file!(disk, "neptunus-boot.txt") == "nep_slot=B\n"

    {qemu, _} = timed("power on: slot B boots", fn -> boot!(vm) end)
    assert ssh!(vm, "cat /etc/neptunus/firmware-version") == "#{version}+test.2\n"
    assert ssh!(vm, "neptunus-firmware status") =~ "running: slot B"
    assert_data_intact!(vm, cert, password)

    # --- 7. an update whose Neptunus cannot start: back to slot B ---------------------------
    ssh!(vm, "echo 60 > /data/etc/firmware-health-timeout")

    {{out, 0}, _} =
      timed("the broken update written to slot A", fn ->
        ssh(vm, "neptunus-firmware update /data/broken.fw")
      end)

    assert out =~ "slot A holds firmware #{version}+broken"
    wait_exit!(qemu, vm)

    {qemu, _} =
      timed("slot A tried, unhealthy, rebooted; slot B boots again", fn ->
        # the broken slot boots, waits for health, reboots; then the good one comes up
        boot!(vm, reboot: qemu)
      end)

    timed("the rollback recorded", fn -> until_marked!(vm, "result=rolled-back") end)
    status = ssh!(vm, "neptunus-firmware status")
    assert status =~ "running: slot B, firmware #{version}+test.2"
    assert status =~ "version=#{version}+broken"
    assert status =~ "reason=Neptunus #{version}+broken did not become healthy within 60s"
    assert console_text(vm) =~ "neptunus: slot A did not come up: back to slot B"
    # what the operator page shows
    assert %{"firmware_update" => %{"result" => "rolled-back", "version" => rolled_back}} =
             health!(vm)

    assert rolled_back == "#{version}+broken"
    assert_data_intact!(vm, cert, password)
    timed("a dive after the rollback", fn -> dive!(vm, password) end)

    kill!(qemu)

    IO.puts(
      "[firmware] power-on to /api/health under qemu (TCG, 1 core, 512 MB): " <>
        "first boot #{div(first_boot_ms, 1000)} s, after an update #{div(second_boot_ms, 1000)} s"
    )
  end

  # --- the emulated board -----------------------------------------------------------------------

  # Starts qemu (or, with reboot:, keeps the running one that reboots by itself) and waits for
  # /api/health. The serial console goes to vm.console (appended).
  defp boot!(vm, opts \\ []) do
    qemu = Keyword.get_lazy(opts, :reboot, fn -> start_qemu!(vm) end)
    health!(vm, @boot_ms)
    # ssh too (it starts beside Neptunus)
    until!(120_000, "ssh", fn -> match?({_, 0}, ssh(vm, "true")) end)
    qemu
  end

  defp start_qemu!(vm) do
    qemu =
      System.find_executable("qemu-system-arm") || flunk("qemu-system-arm: make setup-firmware")

    args = [
      "-M",
      "virt",
      "-cpu",
      "cortex-a15",
      "-smp",
      "1",
      "-m",
      "512",
      "-bios",
      @uboot,
      "-drive",
      "if=none,file=#{vm.disk},format=raw,id=card",
      "-device",
      "virtio-blk-device,drive=card",
      "-netdev",
      "user,id=tether,hostfwd=tcp:127.0.0.1:#{vm.https}-:443,hostfwd=tcp:127.0.0.1:#{vm.ssh}-:22",
      "-device",
      "virtio-net-device,netdev=tether",
      "-display",
      "none",
      "-monitor",
      "none",
      "-chardev",
      "file,id=console,path=#{vm.console}.#{System.unique_integer([:positive])}",
      "-serial",
      "chardev:console"
    ]

    # qemu under a shell that kills it when this test's VM goes away (the port's input
    # closes): no emulated board outlives a failed or interrupted run
    wrapper = ~S"""
    "$@" </dev/null & qemu=$!
    echo "qemu $qemu"
    cat >/dev/null
    kill -9 "$qemu" 2>/dev/null
    wait "$qemu"
    """

    port =
      Port.open({:spawn_executable, System.find_executable("bash")}, [
        :binary,
        :exit_status,
        :stderr_to_stdout,
        args: ["-c", wrapper, "qemu", qemu | args]
      ])

    [_, pid] = Regex.run(~r/qemu (\d+)/, receive_line!(port, ~r/qemu \d+\n/, 30_000))
    {port, pid}
  end

  # every console file of this test, in the order they were made
  defp console_text(vm) do
    Path.wildcard(vm.console <> ".*")
    |> Enum.sort_by(&File.stat!(&1, time: :posix).ctime)
    |> Enum.map_join(&File.read!/1)
  end

  # The power goes: qemu killed. Its shell waits for its input to close before it reaps qemu,
  # so the port is closed too, and the card is only used again once qemu is gone.
  defp kill!({port, pid}) do
    System.cmd("kill", ["-9", pid])
    Port.close(port)
    until!(30_000, "qemu to die", fn -> not File.exists?("/proc/#{pid}") end)
  end

  # After an update the card reboots by itself; /api/health goes away first.
  defp wait_exit!(qemu, vm) do
    until!(300_000, "the reboot", fn -> https_get(vm, "/api/health") == :down end)
    qemu
  end

  defp health!(vm, timeout_ms \\ 60_000) do
    until!(timeout_ms, "/api/health on the card", fn ->
      case https_get(vm, "/api/health") do
        {200, body} -> :jiffy.decode(body, [:return_maps])
        _ -> false
      end
    end)
  end

  defp https_get(vm, path) do
    url = ~c"https://127.0.0.1:#{vm.https}#{path}"
    ssl = [verify: :verify_none]

    case :httpc.request(:get, {url, []}, [ssl: ssl, timeout: 10_000, connect_timeout: 5_000],
           body_format: :binary
         ) do
      {:ok, {{_, status, _}, _, body}} -> {status, body}
      {:error, _} -> :down
    end
  end

  defp cert_fingerprint(vm) do
    {:ok, socket} =
      :ssl.connect(~c"127.0.0.1", vm.https, [verify: :verify_none, active: false], 10_000)

    {:ok, der} = :ssl.peercert(socket)
    :ssl.close(socket)
    :crypto.hash(:sha256, der)
  end

  # the settings, users, keys and what Neptunus wrote survive every update
  defp assert_data_intact!(vm, cert, password) do
    assert cert_fingerprint(vm) == cert
    assert ssh!(vm, "cat /data/neptunus/marker") == "from the first firmware\n"
    assert login_status(vm, password) == 200
  end

  defp login_status(vm, password) do
    body = :jiffy.encode(%{name: "admin", password: password})

    {:ok, {{_, status, _}, _, _}} =
      :httpc.request(
        :post,
        {~c"https://127.0.0.1:#{vm.https}/api/login", [], ~c"application/json", body},
        [ssl: [verify: :verify_none], timeout: 60_000],
        []
      )

    status
  end

  # --- the pilot (the phoenix JS client) --------------------------------------------------------

  defp dive!(vm, password) do
    {out, status} =
      System.cmd("node", [Path.join(@root, "test/firmware/dive.mjs")],
        env: dive_env(vm, password),
        stderr_to_stdout: true
      )

    assert status == 0, "the dive failed:\n#{out}"
    assert out =~ ~s("ok":true)
    out
  end

  defp dive_env(vm, password) do
    [
      {"NEPTUNUS_URL", "https://127.0.0.1:#{vm.https}"},
      {"NEPTUNUS_PASSWORD", password},
      {"NEPTUNUS_VEHICLE", "rov"}
    ]
  end

  # A pilot who keeps the helm until the port is closed (dive.mjs --hold).
  defp hold_helm!(vm, password) do
    node = System.find_executable("node")

    port =
      Port.open({:spawn_executable, node}, [
        :binary,
        :exit_status,
        :stderr_to_stdout,
        args: [Path.join(@root, "test/firmware/dive.mjs"), "--hold"],
        env: Enum.map(dive_env(vm, password), fn {k, v} -> {~c"#{k}", ~c"#{v}"} end)
      ])

    receive_line!(port, "holding", 120_000)
    port
  end

  defp receive_line!(port, text, timeout_ms, acc \\ "") do
    receive do
      {^port, {:data, data}} ->
        acc = acc <> data
        if acc =~ text, do: acc, else: receive_line!(port, text, timeout_ms, acc)

      {^port, {:exit_status, status}} ->
        flunk("exited #{status} before #{inspect(text)}:\n#{acc}")
    after
      timeout_ms -> flunk("no #{inspect(text)} within #{timeout_ms} ms:\n#{acc}")
    end
  end

  # --- updates ----------------------------------------------------------------------------------

  defp ssh_args(vm, extra \\ []) do
    [
      "-p",
      "#{vm.ssh}",
      "-i",
      vm.key,
      "-o",
      "StrictHostKeyChecking=no",
      "-o",
      "UserKnownHostsFile=/dev/null",
      "-o",
      "BatchMode=yes",
      "-o",
      "ConnectTimeout=20",
      "-o",
      "LogLevel=ERROR"
    ] ++ extra ++ ["root@127.0.0.1"]
  end

  defp ssh(vm, command), do: System.cmd("ssh", ssh_args(vm) ++ [command], stderr_to_stdout: true)

  defp ssh!(vm, command) do
    {out, status} = ssh(vm, command)
    assert status == 0, "ssh #{command} failed (#{status}):\n#{out}"
    out
  end

  # the command with the file `input` on its standard input
  defp ssh!(vm, command, input) do
    line = Enum.map_join(ssh_args(vm) ++ [command], " ", &shell_quote/1)

    {out, status} =
      System.cmd("bash", ["-c", "ssh #{line} < #{shell_quote(input)}"], stderr_to_stdout: true)

    assert status == 0, "ssh #{command} < #{input} failed (#{status}):\n#{out}"
    out
  end

  defp shell_quote(word), do: "'" <> String.replace(word, "'", ~S('\'')) <> "'"

  defp ssh_port(vm, command) do
    Port.open({:spawn_executable, System.find_executable("ssh")}, [
      :binary,
      :exit_status,
      :stderr_to_stdout,
      args: ssh_args(vm) ++ [command]
    ])
  end

  defp upload_env(vm), do: [{"SSH_OPTS", Enum.join(Enum.drop(ssh_args(vm), -1), " ")}]

  # what `make upload HOST=127.0.0.1 FW=file` runs (make would turn every exit status into 2),
  # through the card's forwarded SSH port
  defp upload(vm, file) do
    System.cmd(Path.join(@root, "rel/firmware/upload"), ["127.0.0.1", file],
      env: upload_env(vm),
      stderr_to_stdout: true
    )
  end

  # The build's root with its version changed and files of the release replaced, signed with
  # the build's key (as `make firmware` signs its own update).
  defp variant!(dir, root_img, version, replacements) do
    img = Path.join(dir, "root-#{version}.ext4")
    File.cp!(root_img, img)
    version_file = Path.join(dir, "version-#{version}")
    File.write!(version_file, version <> "\n")

    debugfs!(img, [
      "rm /etc/neptunus/firmware-version",
      "write #{version_file} /etc/neptunus/firmware-version"
    ])

    {releases, 0} =
      System.cmd("debugfs", ["-R", "ls -p /opt/neptunus/releases", img], stderr_to_stdout: true)

    [release | _] =
      for [_, name] <- Regex.scan(~r{/\d+/\d+/\d+/\d+/([0-9][^/]*)/}, releases), do: name

    for {path, content} <- replacements do
      local = Path.join(dir, Path.basename(path) <> "-#{version}")
      File.write!(local, content)
      File.chmod!(local, 0o755)
      target = "/opt/neptunus/releases/#{release}/#{path}"

      debugfs!(img, [
        "rm #{target}",
        "write #{local} #{target}",
        "sif #{target} uid 0",
        "sif #{target} gid 0"
      ])
    end

    pack!(img, version, Path.join(dir, "neptunus-#{version}.fw"), nil)
  end

  # A small signed update: a 2 MiB root of noise (it would not boot), signed with `key` (nil:
  # the build's)
  defp small_update!(dir, version, key) do
    content = Path.join(dir, "small-#{version}")
    File.mkdir_p!(content)
    File.write!(Path.join(content, "noise"), :crypto.strong_rand_bytes(2 * @mib))
    img = Path.join(dir, "small-#{version}.ext4")

    {_, 0} =
      System.cmd("mkfs.ext4", ["-q", "-F", "-d", content, img, "4M"], stderr_to_stdout: true)

    pack!(img, version, Path.join(dir, "small-#{version}.fw"), key)
  end

  defp debugfs!(img, commands) do
    script = Path.join(Path.dirname(img), "debugfs.cmds")
    File.write!(script, Enum.join(commands, "\n") <> "\n")
    {out, 0} = System.cmd("debugfs", ["-w", "-f", script, img], stderr_to_stdout: true)
    refute out =~ ~r/(not found|No such file|Could not)/i, "debugfs: #{out}"
  end

  defp pack!(img, version, out, key) do
    env = if key, do: [{"NEPTUNUS_FIRMWARE_KEY", key}], else: []

    {log, status} =
      System.cmd(Path.join(@root, "rel/firmware/pack"), [img, version, out],
        env: env,
        stderr_to_stdout: true
      )

    assert status == 0, "pack failed: #{log}"
    out
  end

  defp flip_byte!(file, offset) do
    {:ok, fd} = :file.open(file, [:read, :write, :binary])
    {:ok, <<byte>>} = :file.pread(fd, offset, 1)
    :ok = :file.pwrite(fd, offset, <<Bitwise.bxor(byte, 0xFF)>>)
    :ok = :file.close(fd)
  end

  defp until_marked!(vm, text) do
    until!(600_000, text, fn -> elem(ssh(vm, "neptunus-firmware status"), 0) =~ text end)
  end

  # --- the card seen from a PC ------------------------------------------------------------------

  defp boot_file!(disk, name) do
    {out, 0} = System.cmd("mtype", ["-i", "#{disk}@@#{@boot_offset}", "::" <> name])
    out
  end

  defp put_boot_file!(disk, name, content) do
    local = Path.join(Path.dirname(disk), name)
    File.write!(local, content)
    {_, 0} = System.cmd("mcopy", ["-o", "-i", "#{disk}@@#{@boot_offset}", local, "::" <> name])
  end

  defp boot_listing(disk) do
    {out, 0} = System.cmd("mdir", ["-b", "-i", "#{disk}@@#{@boot_offset}", "::"])
    out |> String.split("\n", trim: true) |> Enum.map(&(&1 |> String.trim() |> Path.basename()))
  end

  defp slot_digest(disk, offset) do
    {:ok, fd} = :file.open(disk, [:read, :binary, :raw])
    {:ok, data} = :file.pread(fd, offset, @mib)
    :file.close(fd)
    :crypto.hash(:sha256, data)
  end

  # --- waiting and timing -----------------------------------------------------------------------

  defp until!(timeout_ms, what, fun) do
    deadline = System.monotonic_time(:millisecond) + timeout_ms
    until_loop(deadline, what, fun)
  end

  defp until_loop(deadline, what, fun) do
    case fun.() do
      result when result in [false, nil] ->
        if System.monotonic_time(:millisecond) > deadline,
          do: flunk("timed out waiting for #{what}")

        Process.sleep(200)
        until_loop(deadline, what, fun)

      result ->
        result
    end
  end

  defp timed(what, fun) do
    started = System.monotonic_time(:millisecond)
    result = fun.()
    ms = System.monotonic_time(:millisecond) - started
    IO.puts("[firmware] #{what}: #{Float.round(ms / 1000, 1)} s")
    {result, ms}
  end
end
