defmodule Neptunus.Camera.PortProgramTest do
  # the camera port program's `run` end (c_src/neptunus_camera.c), as the dive export uses it
  use ExUnit.Case, async: true

  alias Neptunus.Camera.Program

  defp open(args), do: Program.open(args)

  defp ended(port, acc \\ []) do
    receive do
      {^port, {:data, <<?x, code>>}} -> {Enum.reverse(acc), code}
      {^port, {:data, <<?d, bytes::binary>>}} -> ended(port, [bytes | acc])
      {^port, {:data, _}} -> ended(port, acc)
    after
      Neptunus.Test.Patience.ms() -> flunk("the program's end was not said")
    end
  end

  test "run --linger: after the program's end it waits for the VM to close, so a write then never fails" do
    port = open(["run", "--linger", "--", "/bin/sh", "-c", "printf hello; exit 3"])
    assert {["hello"], 3} = ended(port)

    # acknowledgements written after the end: the port stays open (without --linger the first
    # that finds the program gone fails with EPIPE and closes the port, dropping unread output)
    for _ <- 1..5, do: Port.command(port, <<?a, 5::32>>)
    {:os_pid, os_pid} = Port.info(port, :os_pid)
    assert File.exists?("/proc/#{os_pid}")
    refute_received {^port, {:exit_status, _}}

    # the VM closes its end: the program goes
    :ok = Program.close(port)
    Neptunus.Test.Cluster.wait!(fn -> not File.exists?("/proc/#{os_pid}") end, "the program gone")
  end

  test "run: the program's end is said, then its exit status comes" do
    port = open(["run", "--", "/bin/sh", "-c", "printf hello; exit 3"])
    assert {["hello"], 3} = ended(port)
    assert_receive {^port, {:exit_status, 3}}, Neptunus.Test.Patience.ms()
  end
end
