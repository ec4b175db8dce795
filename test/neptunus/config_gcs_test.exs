defmodule Neptunus.Config.GCSTest do
  use ExUnit.Case, async: true
  doctest Neptunus.Config.GCS

  alias Neptunus.Config.GCS

  @vehicles [%{id: "a"}, %{id: "b"}, %{id: "c"}]
  @key String.duplicate("ab", 32)
  @key2 String.duplicate("cd", 32)

  defp gcs!(env, mode \\ :local), do: GCS.gcs!(env, @vehicles, mode)

  defp refused(env, pattern) do
    error = assert_raise ArgumentError, fn -> gcs!(env) end
    assert error.message =~ pattern
    error.message
  end

  test "off by default, and with off or none" do
    for spec <- [nil, "", "off", "none"] do
      env = if spec, do: %{"NEPTUNUS_MAVLINK_SERVE" => spec}, else: %{}
      assert %{endpoints: [], unsigned: :none, trusted: [], keys: %{}} = gcs!(env)
    end
  end

  test "several endpoints, each with its own link id" do
    %{endpoints: endpoints} =
      gcs!(%{
        "NEPTUNUS_MAVLINK_SERVE" =>
          "udpin:127.0.0.1:14550, tcpin:127.0.0.1:5760,udpout:localhost:14551,udpin:[::1]:14552"
      })

    assert [
             %{kind: :udpin, address: {127, 0, 0, 1}, port: 14_550, loopback: true, link_id: 0},
             %{kind: :tcpin, port: 5760, link_id: 1},
             %{kind: :udpout, address: {127, 0, 0, 1}, port: 14_551, gcs: nil, link_id: 2},
             %{kind: :udpin, address: {0, 0, 0, 0, 0, 0, 0, 1}, loopback: true}
           ] = endpoints
  end

  test "an endpoint beyond loopback needs keys; a udpout there names whose key signs" do
    message = refused(%{"NEPTUNUS_MAVLINK_SERVE" => "udpin:0.0.0.0:14550"}, "signing key")
    assert message =~ "NEPTUNUS_MAVLINK_GCS"

    keys = %{"NEPTUNUS_MAVLINK_GCS" => "topside:pilot:#{@key}"}

    assert %{endpoints: [%{loopback: false}]} =
             gcs!(Map.put(keys, "NEPTUNUS_MAVLINK_SERVE", "udpin:0.0.0.0:14550"))

    refused(Map.put(keys, "NEPTUNUS_MAVLINK_SERVE", "udpout:10.0.0.5:14550"), "@GCS")
    refused(Map.put(keys, "NEPTUNUS_MAVLINK_SERVE", "udpout:10.0.0.5:14550@nobody"), "@GCS")

    assert %{endpoints: [%{gcs: "topside"}]} =
             gcs!(Map.put(keys, "NEPTUNUS_MAVLINK_SERVE", "udpout:10.0.0.5:14550@topside"))
  end

  for bad <- [
        "udp:127.0.0.1:14550",
        "udpin:127.0.0.1",
        "udpin:127.0.0.1:0",
        "udpin:127.0.0.1:70000",
        "udpin:nohost:14550",
        "tcpin:127.0.0.1:5760@x",
        "udpin:127.0.0.1:1,udpin:127.0.0.1:1"
      ] do
    test "refuses the endpoint #{inspect(bad)}" do
      refused(%{"NEPTUNUS_MAVLINK_SERVE" => unquote(bad)}, "NEPTUNUS_MAVLINK_SERVE")
    end
  end

  test "system ids: configured ones kept, the others 1, 2, … in vehicle order around them" do
    assert gcs!(%{}).systems == %{"a" => 1, "b" => 2, "c" => 3}
    assert gcs!(%{"NEPTUNUS_MAVLINK_SYSIDS" => "b=1"}).systems == %{"a" => 2, "b" => 1, "c" => 3}

    assert gcs!(%{"NEPTUNUS_MAVLINK_SYSIDS" => "a=7, c=2"}).systems ==
             %{"a" => 7, "b" => 1, "c" => 2}

    for bad <- ["a=0", "a=255", "a=x", "z=3", "a=1,b=1", "a"] do
      refused(%{"NEPTUNUS_MAVLINK_SYSIDS" => bad}, "NEPTUNUS_MAVLINK_SYSIDS")
    end
  end

  test "keys inline and from a file; names, roles and keys checked" do
    path = Path.join(System.tmp_dir!(), "gcs-keys-#{System.unique_integer([:positive])}")
    File.write!(path, "# ground stations\nqgc pilot #{@key2}  # the laptop\n\n")

    try do
      %{keys: keys} =
        gcs!(%{
          "NEPTUNUS_MAVLINK_GCS" => "topside:main_station:#{String.upcase(@key)}",
          "NEPTUNUS_MAVLINK_GCS_FILE" => path
        })

      assert keys["topside"] == %{
               name: "topside",
               role: :main_station,
               key: Base.decode16!(@key, case: :lower)
             }

      assert keys["qgc"].role == :pilot

      # a keys file others may read is said at boot (the node still starts)
      File.chmod!(path, 0o644)

      log =
        ExUnit.CaptureLog.capture_log(fn ->
          assert %{keys: %{"qgc" => _}} = gcs!(%{"NEPTUNUS_MAVLINK_GCS_FILE" => path})
        end)

      assert log =~ "NEPTUNUS_MAVLINK_GCS_FILE #{path} is open to others (mode 644)"
      File.chmod!(path, 0o600)

      # (other async tests may log meanwhile: only this file's warning is looked for)
      refute ExUnit.CaptureLog.capture_log(fn ->
               gcs!(%{"NEPTUNUS_MAVLINK_GCS_FILE" => path})
             end) =~ "NEPTUNUS_MAVLINK_GCS_FILE #{path}"
    after
      File.rm(path)
    end

    for bad <- [
          "x:pilot",
          "x:captain:#{@key}",
          "x:pilot:#{String.slice(@key, 0, 62)}",
          "x:pilot:#{String.duplicate("zz", 32)}",
          "bad name:pilot:#{@key}",
          "x:pilot:#{@key},x:observer:#{@key2}",
          "x:pilot:#{@key},y:observer:#{@key}",
          "x:main_station:#{@key},y:main_station:#{@key2}"
        ] do
      refused(%{"NEPTUNUS_MAVLINK_GCS" => bad}, "NEPTUNUS_MAVLINK_GCS")
    end

    refused(%{"NEPTUNUS_MAVLINK_GCS_FILE" => "/nonexistent/keys"}, "readable file")
  end

  test "trusted system ids and what unsigned ground stations get beyond loopback" do
    assert %{trusted: [255, 250], unsigned: :watch, mode: :secure} =
             GCS.gcs!(
               %{
                 "NEPTUNUS_MAVLINK_TRUSTED" => "255, 250,255",
                 "NEPTUNUS_MAVLINK_UNSIGNED" => "watch"
               },
               @vehicles,
               :secure
             )

    refused(%{"NEPTUNUS_MAVLINK_TRUSTED" => "0"}, "NEPTUNUS_MAVLINK_TRUSTED")
    refused(%{"NEPTUNUS_MAVLINK_UNSIGNED" => "all"}, "NEPTUNUS_MAVLINK_UNSIGNED")
  end
end
