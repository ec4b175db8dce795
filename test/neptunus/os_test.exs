defmodule Neptunus.OSTest do
  # Changes the time slice of every thread of the test VM: not async. Each test gives the
  # configured slice back.
  use ExUnit.Case, async: false

  alias Neptunus.OS

  doctest Neptunus.OS, only: [port_env: 1]

  setup do
    on_exit(fn ->
      OS.request_time_slice(Application.get_env(:neptunus, :os_time_slice_ns) || 0)
    end)
  end

  # Linux 6.12 and later report a fair thread's slice (custom or default); older kernels 0.
  defp kernel_reports_slices? do
    {:ok, slices} = OS.thread_slices(0)
    Enum.any?(slices, fn {_tid, ns} -> ns > 0 end)
  end

  test "the C library is loaded" do
    assert OS.available?()
  end

  test "a requested slice is set on every thread of the VM, and the kernel's default comes back" do
    {:ok, before} = OS.thread_slices(0)
    assert length(before) >= System.schedulers_online()

    if kernel_reports_slices?() do
      assert {:ok, threads} = OS.request_time_slice(300_000)
      {:ok, slices} = OS.thread_slices(0)
      assert threads == length(slices)
      assert Enum.all?(slices, fn {_tid, ns} -> ns == 300_000 end)

      assert {:ok, _} = OS.request_time_slice(0)
      {:ok, slices} = OS.thread_slices(0)
      [{_, default} | _] = slices
      assert default not in [0, 300_000]
      assert Enum.all?(slices, fn {_tid, ns} -> ns == default end)
    else
      # accepted and ignored: said so, not pretended
      assert OS.request_time_slice(300_000) == {:error, :unsupported}
    end
  end

  test "the node asked for the configured slice at start" do
    ns = Application.fetch_env!(:neptunus, :os_time_slice_ns)
    assert ns == 100_000

    if kernel_reports_slices?() do
      {:ok, slices} = OS.thread_slices(0)
      assert Enum.all?(slices, fn {_tid, slice} -> slice == ns end)
    end
  end

  test "out-of-range slices are refused before any system call" do
    for bad <- [-1, 1, 99_999, 100_000_001, 1.5e5, :fast] do
      assert_raise FunctionClauseError, fn -> OS.request_time_slice(bad) end
    end

    # the C functions check too
    assert_raise ArgumentError, fn -> OS.set_time_slice(50) end
    assert_raise ArgumentError, fn -> OS.time_slices(-1) end
  end

  test "another process' threads; a process that does not exist" do
    port = Port.open({:spawn_executable, System.find_executable("sleep")}, args: ["5"])
    {:os_pid, os_pid} = Port.info(port, :os_pid)
    on_exit(fn -> System.cmd("kill", [Integer.to_string(os_pid)]) end)

    assert {:ok, [{^os_pid, _ns}]} = OS.thread_slices(os_pid)
    assert OS.thread_slices(999_999_999) == {:error, :enoent}
  end

  test "port programs get NEPTUNUS_SLICE_NS while the node asks for a slice" do
    assert OS.port_env(100_000) == [{~c"NEPTUNUS_SLICE_NS", ~c"100000"}]
    assert OS.port_env(nil) == []
  end

  describe "descriptor limit" do
    test "reads the soft and hard RLIMIT_NOFILE; raising sets soft to hard and is idempotent" do
      assert {:ok, {soft, hard}} = OS.fd_limit()
      assert is_integer(soft) and soft > 0
      assert hard == :infinity or hard >= soft
      # the test VM may already run at its hard limit: raising then changes nothing
      assert {:ok, {^soft, raised}} = OS.raise_fd_limit()
      assert {:ok, {^raised, ^raised}} = OS.fd_limit()
      if hard != :infinity, do: assert(raised == hard)
      assert {:ok, {^raised, ^raised}} = OS.raise_fd_limit()
    end

    test "the soft limit is raised in a process started below its hard limit" do
      # a child VM started by a shell with a lower soft limit (its hard limit is ours)
      {:ok, {_, hard}} = OS.fd_limit()
      erl = System.find_executable("erl")
      ebin = :code.lib_dir(:neptunus, :ebin) |> to_string()
      elixir = :code.lib_dir(:elixir, :ebin) |> to_string()

      script =
        ~s|'Elixir.Code':ensure_loaded('Elixir.Neptunus.OS'), | <>
          ~s|io:format("~p ~p ~p~n", ['Elixir.Neptunus.OS':fd_limit(), | <>
          ~s|'Elixir.Neptunus.OS':raise_fd_limit(), 'Elixir.Neptunus.OS':socket_limit()]), | <>
          ~s|halt().|

      {out, 0} =
        System.cmd("sh", [
          "-c",
          ~s|ulimit -Sn 200 && exec "$0" -noshell -pa "$1" -pa "$2" -eval "$3"|,
          erl,
          ebin,
          elixir,
          script
        ])

      hard_text = if hard == :infinity, do: "infinity", else: to_string(hard)

      if hard != :infinity and hard <= 200 do
        assert out =~ "{ok,{200,200}}"
      else
        assert out =~ "{ok,{200,#{hard_text}}} {ok,{200,"
        # the VM's sockets stay within the limit it started with
        assert out =~ ~r/ 200\n$/
      end
    end
  end
end
