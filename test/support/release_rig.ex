defmodule Neptunus.Test.ReleaseRig do
  @moduledoc """
  Helpers for the tests that run a built release as its own OS process (the armhf tarball
  under qemu-user, the install/update/rollback script): HTTP health, `bin/neptunus rpc`, a
  pilot over the WebSocket, the ELF objects of a tree, and qemu-user's registration with the
  kernel (binfmt_misc) so that the node's ARM programs — erts, its helpers, our port program —
  run as they would on the board.
  """
  import ExUnit.Assertions

  alias NeptunusWeb.Test.WSClient

  @doc "`GET path` on 127.0.0.1:`port` (HTTP/1.0): `{status, body}`, or `:down`."
  @spec get(:inet.port_number(), String.t()) :: {non_neg_integer(), binary()} | :down
  def get(port, path) do
    with {:ok, socket} <-
           :gen_tcp.connect(~c"127.0.0.1", port, [:binary, active: false], 5_000),
         :ok <- :gen_tcp.send(socket, "GET #{path} HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n"),
         {:ok, response} <- read_all(socket, <<>>),
         ["HTTP/1." <> <<_, " ", status::binary-size(3)>> <> _, body] <-
           :binary.split(response, "\r\n\r\n") do
      {String.to_integer(status), body}
    else
      _ -> :down
    end
  end

  defp read_all(socket, acc) do
    case :gen_tcp.recv(socket, 0, 5_000) do
      {:ok, data} -> read_all(socket, acc <> data)
      {:error, :closed} -> {:ok, acc}
      {:error, reason} -> {:gen_tcp.close(socket), reason}
    end
  end

  @doc "Waits up to `timeout_ms` for `/api/health` to answer 200; its decoded body."
  @spec until_healthy(:inet.port_number(), non_neg_integer()) :: map()
  def until_healthy(port, timeout_ms) do
    deadline = System.monotonic_time(:millisecond) + timeout_ms
    until_healthy_loop(port, deadline)
  end

  defp until_healthy_loop(port, deadline) do
    case get(port, "/api/health") do
      {200, body} ->
        :jiffy.decode(body, [:return_maps])

      _ ->
        if System.monotonic_time(:millisecond) > deadline,
          do: flunk("the release did not answer /api/health on port #{port}")

        Process.sleep(500)
        until_healthy_loop(port, deadline)
    end
  end

  @doc "Runs `bin/neptunus rpc expr` of release `rel` with `env`; what it wrote (exit 0)."
  @spec rpc!(Path.t(), String.t(), [{String.t(), String.t()}]) :: String.t()
  def rpc!(rel, expr, env) do
    {out, status} =
      System.cmd(Path.join(rel, "bin/neptunus"), ["rpc", expr], env: env, stderr_to_stdout: true)

    assert status == 0, "rpc #{expr} failed (#{status}):\n#{out}"
    out
  end

  @doc "The regular files under `dir` that are ELF objects (programs, shared libraries)."
  @spec elf_files(Path.t()) :: [Path.t()]
  def elf_files(dir) do
    dir
    |> Path.join("**")
    |> Path.wildcard(match_dot: true)
    |> Enum.filter(fn path ->
      File.regular?(path) and
        match?({:ok, <<0x7F, "ELF">>}, File.open(path, [:read, :binary], &IO.binread(&1, 4)))
    end)
  end

  @doc """
  Makes the kernel run 32-bit ARM ELF programs with qemu-user (Debian's qemu-user-static
  registration, `/usr/lib/binfmt.d/qemu-arm.conf`), mounting binfmt_misc first if needed.
  Needs root; `:ok` when it is (or already was) registered.
  """
  @spec register_qemu_arm!() :: :ok
  def register_qemu_arm! do
    dir = "/proc/sys/fs/binfmt_misc"

    unless File.exists?(Path.join(dir, "register")) do
      {out, status} =
        System.cmd("mount", ["-t", "binfmt_misc", "binfmt_misc", dir], stderr_to_stdout: true)

      assert status == 0, "cannot mount binfmt_misc (qemu-user needs it; run as root): #{out}"
    end

    unless File.exists?(Path.join(dir, "qemu-arm")) do
      conf = "/usr/lib/binfmt.d/qemu-arm.conf"
      assert File.exists?(conf), "#{conf} is missing: make setup-armhf installs qemu-user-static"
      File.write!(Path.join(dir, "register"), String.trim(File.read!(conf)))
    end

    assert File.read!(Path.join(dir, "qemu-arm")) =~ "enabled"
    :ok
  end

  @doc """
  A pilot over the WebSocket on `port`: joins `vehicle:<id>` and takes the helm. Returns
  `{ws, join_ref, topic, epoch}`; the connection belongs to the calling process.
  """
  @spec pilot!(:inet.port_number(), String.t()) :: {pid(), String.t(), String.t(), integer()}
  def pilot!(port, id) do
    {:ok, ws} = WSClient.connect(port, "/socket/websocket?vsn=2.0.0&name=Pilot")
    topic = "vehicle:" <> id
    jr = WSClient.unique_ref()
    {:ok, _} = WSClient.join(ws, topic, %{}, jr)
    ref = WSClient.unique_ref()
    :ok = WSClient.push(ws, jr, ref, topic, "request_control", %{})

    [_, _, _, _, %{"status" => "ok", "response" => %{"grant" => %{"epoch" => epoch}}}] =
      WSClient.recv_until(ws, &match?([_, ^ref, _, "phx_reply", _], &1), 30_000)

    {ws, jr, topic, epoch}
  end

  @doc "Sends the pilot's thrust (motion mode) and a heartbeat, without waiting for replies."
  @spec thrust({pid(), String.t(), String.t(), integer()}, number()) :: :ok
  def thrust({ws, jr, topic, epoch}, surge) do
    payload = %{"mode" => "motion", "surge" => surge, "heave" => 0, "yaw" => 0, "epoch" => epoch}
    :ok = WSClient.push(ws, jr, WSClient.unique_ref(), topic, "thrust", payload)
    :ok = WSClient.push(ws, jr, WSClient.unique_ref(), topic, "heartbeat", %{})
  end
end
