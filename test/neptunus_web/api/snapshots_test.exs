defmodule NeptunusWeb.API.SnapshotsTest do
  # Snapshots against the running endpoint: POST /api/vehicles/<id>/snapshot, the vehicle
  # channel's `snapshot`, GET /api/snapshots…; saved in a scratch recordings directory.
  use ExUnit.Case, async: false

  import NeptunusWeb.Test.Wire, only: [secure!: 2, settings!: 1, start_vehicle!: 1, client!: 2]

  alias Neptunus.Camera.{Frame, MJPEG, Snapshot, Source}
  alias Neptunus.PubSub
  alias Neptunus.Vehicle.Camera
  alias NeptunusWeb.Auth.Token
  alias NeptunusWeb.Test.{Wire, WSClient}

  @moduletag :tmp_dir
  @moduletag :capture_log
  @secret "snapshot-test-secret-" <> String.duplicate("s", 20)
  @script Path.expand("../../fixtures/camera/fake_camera.sh", __DIR__)

  setup %{tmp_dir: dir} do
    settings!(recording_dir: dir)
    :ok
  end

  # a vehicle with `camera`, once its camera has sent a keyframe
  defp vehicle!(camera) do
    id = "snap-#{System.unique_integer([:positive])}"
    PubSub.subscribe(Camera.topic(id))
    {:ok, _} = Neptunus.Fleet.start_vehicle(%{id: id, board: :simulated, camera: camera})
    on_exit(fn -> Neptunus.Fleet.stop_vehicle(id) end)
    await_keyframe()
    id
  end

  defp await_keyframe do
    assert_receive {:pubsub, _, "frame", %{frame: %Frame{} = frame}}
    if frame.keyframe, do: frame, else: await_keyframe()
  end

  defp request(method, path, headers \\ []) do
    url = ~c"http://127.0.0.1:#{Wire.port()}#{path}"

    request =
      if method == :post, do: {url, headers, ~c"application/json", ""}, else: {url, headers}

    {:ok, {{_, status, _}, resp_headers, body}} =
      :httpc.request(method, request, [], body_format: :binary)

    {status, Map.new(resp_headers, fn {k, v} -> {to_string(k), to_string(v)} end), body}
  end

  defp json(body), do: :jiffy.decode(body, [:return_maps, {:null_term, nil}])

  defp comment(<<0xFF, 0xD8, rest::binary>>), do: segments(rest)

  defp segments(<<0xFF, 0xFE, len::16, rest::binary>>),
    do: binary_part(rest, 0, len - 2) |> json()

  defp segments(<<0xFF, _m, len::16, rest::binary>>),
    do: segments(binary_part(rest, len - 2, byte_size(rest) - len + 2))

  test "an H.264 camera: the current picture decoded, saved with the recordings, listed, served",
       %{tmp_dir: dir} do
    {:ok, camera} = Source.parse("testsrc@h264@320x240@15")
    id = vehicle!(camera)
    # the vehicle knows its depth and heading
    PubSub.subscribe("vehicle:" <> id)

    assert_receive {:pubsub, _, "telemetry", %{estimate: %{depth: d, heading: h}}}
                   when is_number(d) and is_number(h)

    {201, _, body} = request(:post, "/api/vehicles/#{id}/snapshot")
    assert %{"snapshot" => snap} = json(body)

    assert %{"vehicle" => ^id, "name" => name, "width" => 320, "height" => 240, "url" => url} =
             snap

    assert Snapshot.valid?(id, name) and String.starts_with?(name, id <> "-")
    assert snap["depth"] != nil and name =~ ~r/-\d+\.\d\dm-\d{3}deg\.jpg$/

    path = Path.join([dir, id, "snapshots", name])
    jpeg = File.read!(path)
    assert MJPEG.size(jpeg) == {320, 240}

    assert %{"vehicle" => ^id, "width" => 320, "camera" => "testsrc@h264@320x240@15"} =
             meta = comment(jpeg)

    assert meta["taken_at"] =~ ~r/^\d{4}-\d\d-\d\dT/
    assert is_number(meta["depth_m"]) and is_number(meta["heading_deg"])

    {200, _, body} = request(:get, "/api/snapshots?vehicle=#{id}")
    assert [%{"name" => ^name, "bytes" => bytes, "url" => ^url}] = json(body)["snapshots"]
    assert bytes == byte_size(jpeg)

    {200, headers, served} = request(:get, url)
    assert served == jpeg and headers["content-type"] == "image/jpeg"

    {404, _, _} = request(:get, "/api/snapshots/#{id}/../../etc/passwd")
    {404, _, _} = request(:get, "/api/snapshots/#{id}/#{id}-20260101-000000.000Z-nam-nadeg.jpg")
    {400, _, _} = request(:get, "/api/snapshots?vehicle=../x")
  end

  test "an MJPEG camera: its newest image, with the comment", %{tmp_dir: _dir} do
    camera = %{kind: :exec, codec: :mjpeg, program: "/bin/sh", args: [@script, "0"]}
    id = vehicle!(camera)
    {201, _, body} = request(:post, "/api/vehicles/#{id}/snapshot")
    %{"snapshot" => %{"url" => url}} = json(body)
    {200, _, jpeg} = request(:get, url)
    assert %{"vehicle" => ^id} = comment(jpeg)

    frames = [
      File.read!("test/fixtures/camera/frame1.jpg"),
      File.read!("test/fixtures/camera/frame2.jpg")
    ]

    assert MJPEG.size(jpeg) == MJPEG.size(hd(frames))
  end

  test "the vehicle channel's snapshot: pending at once, the result as an event" do
    {:ok, camera} = Source.parse("testsrc@h264@320x240@15")
    id = vehicle!(camera)
    %{ws: ws, jr: jr, topic: topic} = client!("vehicle:" <> id, %{"name" => "snapper"})
    assert {"ok", %{"status" => "pending"}} = Wire.push_and_reply(ws, jr, topic, "snapshot", %{})

    assert %{"ok" => true, "snapshot" => %{"vehicle" => ^id, "name" => name}} =
             Wire.event!(ws, "snapshot", fn _ -> true end)

    {200, _, body} = request(:get, "/api/snapshots")
    assert Enum.any?(json(body)["snapshots"], &(&1["name"] == name))
    WSClient.close(ws)
  end

  test "refusals: no camera, unknown vehicle, recording off, another site, not logged in" do
    other = start_vehicle!("nocam")
    {404, _, body} = request(:post, "/api/vehicles/#{other.id}/snapshot")
    assert json(body)["error"] =~ "has no camera"
    {404, _, body} = request(:post, "/api/vehicles/nope/snapshot")
    assert json(body)["error"] =~ "unknown vehicle"
    {404, _, _} = request(:post, "/api/vehicles/#{other.id}/other")
    {405, _, _} = request(:get, "/api/vehicles/#{other.id}/snapshot")

    camera = %{kind: :exec, codec: :mjpeg, program: "/bin/sh", args: [@script, "0"]}
    id = vehicle!(camera)

    {403, _, body} =
      request(:post, "/api/vehicles/#{id}/snapshot", [{~c"origin", ~c"http://evil.example"}])

    assert json(body)["error"] =~ "origin not allowed"

    settings!(recording_dir: nil)
    {409, _, body} = request(:post, "/api/vehicles/#{id}/snapshot")
    assert json(body)["error"] =~ "recording is off"
  end

  test "secure mode: a token of any role takes and sees snapshots; none is refused", %{
    tmp_dir: dir
  } do
    camera = %{kind: :exec, codec: :mjpeg, program: "/bin/sh", args: [@script, "0"]}
    id = vehicle!(camera)
    secure!(@secret, %{"olga" => %{name: "olga", role: :observer, hash: "unused"}})
    settings!(recording_dir: dir)

    {401, _, _} = request(:post, "/api/vehicles/#{id}/snapshot")
    {401, _, _} = request(:get, "/api/snapshots")
    token = Token.sign("olga", @secret, System.os_time(:second), 600)
    auth = [{~c"authorization", String.to_charlist("Bearer " <> token)}]
    {201, _, body} = request(:post, "/api/vehicles/#{id}/snapshot", auth)
    %{"snapshot" => %{"url" => url}} = json(body)
    {200, _, _} = request(:get, url, auth)
  end
end
