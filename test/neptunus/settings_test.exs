defmodule Neptunus.SettingsTest do
  use ExUnit.Case, async: true

  import ExUnit.CaptureLog

  alias Neptunus.Settings
  alias Neptunus.Settings.Rules

  @moduletag :tmp_dir

  defp start(dir, opts \\ []) do
    start_supervised!(
      {Settings, Keyword.merge([dir: dir, name: nil], opts)},
      id: make_ref(),
      restart: :temporary
    )
  end

  test "put, get, delete; per scope", %{tmp_dir: dir} do
    s = start(dir)
    alice = {:user, "alice"}

    assert Settings.get(s, alice, "gamepad.mapping") == :error
    assert Settings.put(s, alice, "gamepad.mapping", %{"0" => "stop"}) == :ok
    assert Settings.get(s, alice, "gamepad.mapping") == {:ok, %{"0" => "stop"}}
    assert Settings.get(s, {:user, "bob"}, "gamepad.mapping") == :error
    assert Settings.get(s, {:vehicle, "alice"}, "gamepad.mapping") == :error
    assert Settings.put(s, {:vehicle, "neptunus-1"}, "camera.rotation", 180) == :ok
    assert Settings.all(s, alice) == %{"gamepad.mapping" => %{"0" => "stop"}}

    assert Settings.delete(s, alice, "gamepad.mapping") == :ok
    assert Settings.get(s, alice, "gamepad.mapping") == :error
    assert Settings.delete(s, alice, "never.set") == :ok
    assert Settings.get(s, {:vehicle, "neptunus-1"}, "camera.rotation") == {:ok, 180}
  end

  test "persisted: a new store on the same directory reads what the last one wrote",
       %{tmp_dir: dir} do
    first = start(dir)
    assert Settings.put(first, {:user, "alice"}, "a", [1, 2.5, "x", nil, true]) == :ok
    assert Settings.put(first, {:vehicle, "v"}, "b", %{"k" => "v"}) == :ok
    stop_supervised_pid(first)

    second = start(dir)
    assert Settings.get(second, {:user, "alice"}, "a") == {:ok, [1, 2.5, "x", nil, true]}
    assert Settings.get(second, {:vehicle, "v"}, "b") == {:ok, %{"k" => "v"}}
    assert File.regular?(Rules.path(dir, {:user, "alice"}))
    # no temporary file left behind
    assert dir |> Path.join("**/*.tmp-*") |> Path.wildcard() == []
  end

  test "bad scopes, keys and values are refused and change nothing", %{tmp_dir: dir} do
    s = start(dir)
    assert Settings.put(s, {:user, "a"}, "k", 1) == :ok

    assert {:error, "a key must be" <> _} = Settings.put(s, {:user, "a"}, "../k", 2)
    assert {:error, "a value must be" <> _} = Settings.put(s, {:user, "a"}, "k", {:tuple})

    assert {:error, "a value must be at most" <> _} =
             Settings.put(s, {:user, "a"}, "k", String.duplicate("x", 20_000))

    assert {:error, "a user name must be" <> _} = Settings.put(s, {:user, ""}, "k", 1)
    assert {:error, "a scope must be" <> _} = Settings.put(s, :nobody, "k", 1)
    assert {:error, "a key must be" <> _} = Settings.delete(s, {:user, "a"}, "")
    assert Settings.get(s, {:user, ""}, "k") == :error
    assert Settings.get(s, {:user, "a"}, "../k") == :error
    assert Settings.all(s, :nobody) == %{}

    assert Settings.get(s, {:user, "a"}, "k") == {:ok, 1}
    assert ls(dir) == ["user/" <> Path.basename(Rules.path(dir, {:user, "a"}))]
  end

  test "a failed write keeps the previous value, in memory and on disk", %{tmp_dir: dir} do
    test = self()
    fail? = :atomics.new(1, [])

    failing_sync = fn io ->
      send(test, :synced)
      if :atomics.get(fail?, 1) == 1, do: {:error, :enospc}, else: :file.sync(io)
    end

    s = start(dir, sync: failing_sync)
    assert Settings.put(s, {:user, "a"}, "k", "old") == :ok
    assert_received :synced
    :atomics.put(fail?, 1, 1)

    log =
      capture_log(fn ->
        assert {:error, "cannot store the setting: no space left on device"} =
                 Settings.put(s, {:user, "a"}, "k", "new")

        assert {:error, "cannot store the setting: " <> _} = Settings.delete(s, {:user, "a"}, "k")
      end)

    assert log =~ "cannot write"
    assert_received :synced
    assert Settings.get(s, {:user, "a"}, "k") == {:ok, "old"}
    assert dir |> Path.join("**/*.tmp-*") |> Path.wildcard() == []
    stop_supervised_pid(s)

    assert Settings.get(start(dir), {:user, "a"}, "k") == {:ok, "old"}
  end

  test "an unwritable directory is an error, not a crash", %{tmp_dir: dir} do
    File.write!(Path.join(dir, "user"), "a file where the user directory would be")
    s = start(dir)

    capture_log(fn ->
      assert {:error, "cannot store the setting: " <> _} = Settings.put(s, {:user, "a"}, "k", 1)
    end)

    assert Settings.get(s, {:user, "a"}, "k") == :error
    assert Process.alive?(s)
  end

  test "a corrupt file is reported, moved aside, and the scope starts empty", %{tmp_dir: dir} do
    path = Rules.path(dir, {:user, "a"})
    File.mkdir_p!(Path.dirname(path))
    File.write!(path, ~s({"user": "a", "settings": {"k": 1))

    s = start(dir)

    log = capture_log(fn -> assert Settings.get(s, {:user, "a"}, "k") == :error end)
    assert log =~ "[error]"
    assert log =~ "#{path} is corrupt (invalid JSON"
    assert log =~ "moved aside as #{path}.corrupt-"
    assert Process.alive?(s)

    assert [aside] = Path.wildcard(path <> ".corrupt-*")
    assert File.read!(aside) == ~s({"user": "a", "settings": {"k": 1)
    refute File.exists?(path)

    # the scope works again, and the next store reads the new file
    assert Settings.put(s, {:user, "a"}, "k", 2) == :ok
    stop_supervised_pid(s)
    assert Settings.get(start(dir), {:user, "a"}, "k") == {:ok, 2}
  end

  test "a file of another scope is not used", %{tmp_dir: dir} do
    path = Rules.path(dir, {:user, "a"})
    File.mkdir_p!(Path.dirname(path))
    File.write!(path, Rules.encode_file({:user, "b"}, %{"k" => 1}))
    s = start(dir)

    log = capture_log(fn -> assert Settings.get(s, {:user, "a"}, "k") == :error end)
    assert log =~ "is corrupt (the file is not of user \"a\")"
  end

  test "needs a directory" do
    Process.flag(:trap_exit, true)

    assert {:error, "Neptunus.Settings needs a :dir" <> _} =
             Settings.start_link(dir: nil, name: nil)
  end

  test "the node runs one, on the configured directory" do
    dir = Application.fetch_env!(:neptunus, :settings_dir)
    assert is_binary(dir)
    assert is_pid(Process.whereis(Settings))
    assert :sys.get_state(Settings).dir == dir
  end

  defp stop_supervised_pid(pid) do
    ref = Process.monitor(pid)
    GenServer.stop(pid)
    assert_receive {:DOWN, ^ref, :process, ^pid, _}
  end

  defp ls(dir) do
    dir
    |> Path.join("**/*")
    |> Path.wildcard()
    |> Enum.filter(&File.regular?/1)
    |> Enum.map(&Path.relative_to(&1, dir))
  end
end
