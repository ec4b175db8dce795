defmodule Neptunus.ReleaseTest do
  # The deployable node: `mix release` (MIX_ENV=prod, as `make release` runs it) builds a
  # node that boots, serves the pages and the API, loads its C library and stops cleanly;
  # the systemd unit in rel/ verifies against it.
  use ExUnit.Case, async: false

  import Neptunus.Test.Vehicles, only: [free_port: 0]

  @moduletag :external
  @moduletag timeout: 600_000

  @root Path.expand("..", __DIR__)

  defp get(port, path) do
    case :httpc.request(:get, {~c"http://127.0.0.1:#{port}#{path}", []}, [timeout: 2_000],
           body_format: :binary
         ) do
      {:ok, {{_, status, _}, _headers, body}} -> {status, body}
      {:error, _} -> :down
    end
  end

  defp until_up(port, 0), do: flunk("the release did not answer on port #{port}")

  defp until_up(port, n) do
    case get(port, "/api/health") do
      {200, body} ->
        body

      _ ->
        Process.sleep(250)
        until_up(port, n - 1)
    end
  end

  @tag :tmp_dir
  test "mix release builds a node that starts, serves and stops", %{tmp_dir: dir} do
    rel = Path.join(dir, "neptunus")
    mix = System.find_executable("mix")

    {output, status} =
      System.cmd(mix, ["release", "--overwrite", "--path", rel],
        cd: @root,
        env: [{"MIX_ENV", "prod"}, {"MIX_BUILD_PATH", nil}],
        stderr_to_stdout: true
      )

    assert status == 0, "mix release failed:\n#{output}"
    assert File.read!(Path.join(rel, "releases/0.1.0/vm.args")) =~ "+sbwt none"

    port = free_port()
    bin = Path.join(rel, "bin/neptunus")

    env = [
      {"NEPTUNUS_PORT", "#{port}"},
      {"NEPTUNUS_RECORDINGS", Path.join(dir, "recordings")},
      {"RELEASE_NODE", "neptunus_release_test_#{port}"},
      {"RELEASE_TMP", dir}
    ]

    # started with a low soft descriptor limit (as a service gets), which the start script
    # raises to the hard limit before the VM starts
    sh = System.find_executable("sh")

    node =
      Port.open({:spawn_executable, sh}, [
        :binary,
        :exit_status,
        :stderr_to_stdout,
        args: ["-c", ~s|ulimit -Sn 512 && exec "$0" start|, bin],
        env: Enum.map(env, fn {k, v} -> {String.to_charlist(k), String.to_charlist(v)} end)
      ])

    try do
      health = :jiffy.decode(until_up(port, 120), [:return_maps])
      assert %{"status" => "ok", "vehicles" => [%{"id" => "neptunus-1"}]} = health
      assert {200, page} = get(port, "/")
      assert page =~ "/assets/app.js"
      assert {200, _} = get(port, "/assets/app.js")

      {loaded, 0} =
        System.cmd(bin, ["rpc", "IO.write(Neptunus.Dynamics.Native.available?())"], env: env)

      assert loaded == "true"

      {limits, 0} =
        System.cmd(
          bin,
          ["rpc", "IO.write(inspect({Neptunus.OS.fd_limit(), Neptunus.OS.socket_limit()}))"],
          env: env
        )

      {:ok, {_, hard}} = Neptunus.OS.fd_limit()

      if hard != :infinity and hard > 512 do
        assert limits == inspect({{:ok, {hard, hard}}, hard})
      end

      # the vehicle records to the configured directory
      assert [_file] =
               Path.wildcard(Path.join([dir, "recordings", "neptunus-1", "*", "entries-*.log"]))
    after
      {_, _} = System.cmd(bin, ["stop"], env: env, stderr_to_stdout: true)
    end

    assert_receive {^node, {:exit_status, 0}}, 15_000
    assert get(port, "/api/health") == :down

    # the systemd unit, pointed at this release
    if analyze = System.find_executable("systemd-analyze") do
      unit =
        @root
        |> Path.join("rel/neptunus.service")
        |> File.read!()
        |> String.replace("/opt/neptunus", rel)

      path = Path.join(dir, "neptunus.service")
      File.write!(path, unit)
      {out, status} = System.cmd(analyze, ["verify", path], stderr_to_stdout: true)
      problems = if status == 0, do: String.trim(out), else: "exit #{status}: #{out}"
      assert problems == "", "systemd-analyze verify:\n#{problems}"
    end
  end
end
