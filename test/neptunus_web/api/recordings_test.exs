defmodule NeptunusWeb.API.RecordingsTest do
  # /api/recordings against the running endpoint; the recording directory is switched at run
  # time (the web settings, which the API reads at every request) and restored after each test.
  use ExUnit.Case, async: false

  import NeptunusWeb.Test.Wire, only: [secure!: 2, secure!: 3, raw_get: 1]

  alias Neptunus.PubSub
  alias Neptunus.Vehicle.{Recorder, Telemetry}
  alias NeptunusWeb.Auth.Token

  @moduletag :tmp_dir
  @moduletag :capture_log
  @secret "recordings-test-secret-" <> String.duplicate("y", 20)

  setup %{tmp_dir: dir} do
    NeptunusWeb.Test.Wire.settings!(recording_dir: dir)
    id = "api-rec-#{System.unique_integer([:positive])}"
    start_supervised!({Recorder, id: id, recording: [dir: dir]})
    _ = Recorder.status(id)

    for i <- 1..30 do
      payload = %{t: i * 0.05, measurement: %{depth: i / 100, heading: 1.5}, link: %{up: true}}
      PubSub.broadcast(Telemetry.topic(id), "telemetry", payload)
    end

    PubSub.broadcast(Telemetry.topic(id), "stopped", %{reason: "deadman"})
    [file] = Recorder.status(id).files
    {:ok, id: id, name: Path.basename(file)}
  end

  defp port, do: Application.fetch_env!(:neptunus, :endpoint).port

  defp get(path, headers \\ []) do
    url = ~c"http://127.0.0.1:#{port()}#{path}"

    {:ok, {{_, status, _}, resp_headers, body}} =
      :httpc.request(:get, {url, headers}, [], body_format: :binary)

    {status, Map.new(resp_headers, fn {k, v} -> {to_string(k), to_string(v)} end), body}
  end

  defp json(body), do: :jiffy.decode(body, [:return_maps, {:null_term, nil}])

  test "lists the recordings, of all vehicles or one", %{id: id, name: name} do
    {200, _, body} = get("/api/recordings")
    assert %{"recording" => true, "recordings" => list} = json(body)

    assert %{"vehicle" => ^id, "name" => ^name, "bytes" => bytes} =
             Enum.find(list, &(&1["vehicle"] == id))

    assert bytes > 0

    {200, _, body} = get("/api/recordings?vehicle=#{id}")
    assert [%{"vehicle" => ^id}] = json(body)["recordings"]

    {400, _, body} = get("/api/recordings?vehicle=../etc")
    assert json(body)["error"] =~ "vehicle id"
  end

  test "exports the telemetry as CSV, including what the recorder still buffered", %{
    id: id,
    name: name
  } do
    {200, headers, csv} = get("/api/recordings/#{id}/#{name}")
    assert headers["content-type"] =~ "text/csv"
    assert headers["content-disposition"] =~ ~s(attachment; filename="#{id}-)

    [header | rows] = String.split(csv, "\n", trim: true)
    assert header == "time,link.up,measurement.depth,measurement.heading,t"
    assert length(rows) == 30
    assert rows |> hd() |> String.split(",") |> tl() == ["1", "0.01", "1.5", "0.05"]
  end

  test "exports JSON lines with every N-th telemetry entry and every event", %{id: id, name: name} do
    {200, headers, body} = get("/api/recordings/#{id}/#{name}?format=jsonl&every=10")
    assert headers["content-type"] =~ "ndjson"
    lines = body |> String.split("\n", trim: true) |> Enum.map(&json/1)
    assert Enum.map(lines, & &1["event"]) == ["telemetry", "telemetry", "telemetry", "stopped"]
    assert Enum.map(Enum.take(lines, 3), & &1["payload"]["t"]) == [0.05, 0.55, 1.05]
  end

  test "CSV honours every and max too", %{id: id, name: name} do
    {200, _, csv} = get("/api/recordings/#{id}/#{name}?every=10")
    [_header | rows] = String.split(csv, "\n", trim: true)
    assert Enum.map(rows, &(&1 |> String.split(",") |> List.last())) == ["0.05", "0.55", "1.05"]

    {200, _, csv} = get("/api/recordings/#{id}/#{name}?max=7")
    assert csv |> String.split("\n", trim: true) |> length() == 1 + 6
  end

  test "a long recording is streamed in chunks, the same bytes as the export in memory", %{
    tmp_dir: dir,
    id: id
  } do
    long = "api-long-#{System.unique_integer([:positive])}"
    start_supervised!({Recorder, id: long, recording: [dir: dir]}, id: :long)
    _ = Recorder.status(long)

    # ≈ 10 000 entries, several 64 KiB chunks of CSV; one event in the middle
    for i <- 1..10_000 do
      if i == 5_000, do: PubSub.broadcast(Telemetry.topic(long), "stopped", %{reason: "test"})

      payload = %{t: i * 0.05, measurement: %{depth: i / 1000, heading: 0.5}, extra: %{n: i}}
      PubSub.broadcast(Telemetry.topic(long), "telemetry", payload)
    end

    [file] = Recorder.status(long).files
    name = Path.basename(file)
    {200, _headers, csv} = get("/api/recordings/#{long}/#{name}")
    assert byte_size(csv) > 3 * 65_536
    # httpc hides the encoding: read the headers off the socket
    {200, raw_headers, _, socket} = raw_get("/api/recordings/#{long}/#{name}")
    :gen_tcp.close(socket)
    assert raw_headers["transfer-encoding"] =~ ~r/chunked/i
    Recorder.sync(long)

    assert csv ==
             file
             |> Neptunus.Recording.entries()
             |> Neptunus.Recording.csv()
             |> IO.iodata_to_binary()

    assert csv |> String.split("\n", trim: true) |> length() == 10_001

    {200, _, jsonl} = get("/api/recordings/#{long}/#{name}?format=jsonl")
    assert jsonl |> String.split("\n", trim: true) |> length() == 10_001
    _ = id
  end

  test "max: JSON lines thinned to at most M telemetry entries", %{id: id, name: name} do
    {200, _, body} = get("/api/recordings/#{id}/#{name}?format=jsonl&max=7")
    lines = body |> String.split("\n", trim: true) |> Enum.map(&json/1)
    telemetry = Enum.filter(lines, &(&1["event"] == "telemetry"))
    # 30 entries, at most 7: every 5th
    assert Enum.map(telemetry, &round(&1["payload"]["t"] * 100)) == [5, 30, 55, 80, 105, 130]
    assert List.last(lines)["event"] == "stopped"
  end

  test "bad requests change nothing and say why", %{id: id, name: name} do
    for {path, status, message} <- [
          {"/api/recordings/#{id}/#{name}?format=xml", 400, "format must be csv or jsonl"},
          {"/api/recordings/#{id}/#{name}?every=0", 400, "every must be an integer"},
          {"/api/recordings/#{id}/#{name}?format=jsonl&max=x", 400, "max must be an integer"},
          {"/api/recordings/#{id}/20200101-000000Z-1.log", 404, "no such recording"},
          {"/api/recordings/#{id}/..%2F..%2Fetc%2Fpasswd", 404, "no such recording"},
          {"/api/recordings/#{id}", 404, "no such recording"},
          {"/api/recordings/#{id}/#{name}/x", 404, "no such recording"}
        ] do
      {^status, _, body} = get(path)
      assert json(body)["error"] =~ message, "#{path}: #{body}"
    end

    {405, _, _} =
      :httpc.request(:delete, {~c"http://127.0.0.1:#{port()}/api/recordings", []}, [],
        body_format: :binary
      )
      |> then(fn {:ok, {{_, status, _}, h, b}} -> {status, h, b} end)
  end

  test "recording off: an empty list, exports 404" do
    NeptunusWeb.Test.Wire.settings!(recording_dir: nil)
    {200, _, body} = get("/api/recordings")
    assert json(body) == %{"recording" => false, "recordings" => []}
    {404, _, body} = get("/api/recordings/a/20200101-000000Z-1.log")
    assert json(body)["error"] =~ "recording is off"
  end

  test "in secure mode recordings need a token (any role)", %{id: id, name: name} do
    users = %{"olga" => %{name: "olga", role: :observer, hash: "unused"}}

    secure!(@secret, users)

    {401, _, body} = get("/api/recordings")
    assert json(body)["error"] =~ "log in to see recordings"
    {401, _, _} = get("/api/recordings/#{id}/#{name}?token=forged")

    token = Token.sign("olga", @secret, System.os_time(:second), 600)
    {200, _, _} = get("/api/recordings?token=#{token}")

    {200, _, _} =
      get("/api/recordings/#{id}/#{name}", [
        {~c"authorization", ~c"Bearer " ++ String.to_charlist(token)}
      ])
  end

  defp delete(path, headers \\ []) do
    url = ~c"http://127.0.0.1:#{port()}#{path}"

    {:ok, {{_, status, _}, _headers, body}} =
      :httpc.request(:delete, {url, headers}, [], body_format: :binary)

    {status, json(body)}
  end

  # a finished recording of the vehicle, older than the one being written
  defp old_recording!(dir, id) do
    name = "20200101-000000Z-1.log"
    path = Path.join([dir, id, name])
    {:ok, log} = :disk_log.open(name: {__MODULE__, make_ref()}, file: String.to_charlist(path))
    :ok = :disk_log.log(log, {1, "telemetry", %{t: 0.0}})
    :ok = :disk_log.close(log)
    {name, path}
  end

  test "DELETE removes a finished recording, never the one being written", %{
    id: id,
    name: name,
    tmp_dir: dir
  } do
    {old, path} = old_recording!(dir, id)

    assert {200, %{"deleted" => %{"vehicle" => ^id, "name" => ^old}}} =
             delete("/api/recordings/#{id}/#{old}")

    refute File.exists?(path)
    {200, _, body} = get("/api/recordings?vehicle=#{id}")
    assert [%{"name" => ^name}] = json(body)["recordings"]

    assert {409, %{"error" => error}} = delete("/api/recordings/#{id}/#{name}")
    assert error =~ "being recorded now"
    assert File.exists?(Path.join([dir, id, name]))

    assert {404, _} = delete("/api/recordings/#{id}/#{old}")
    assert {404, _} = delete("/api/recordings/#{id}/..%2F..%2Fetc%2Fpasswd")
    assert {404, _} = delete("/api/recordings/#{id}")
  end

  test "in secure mode only a pilot or the main station may delete", %{id: id, tmp_dir: dir} do
    {old, path} = old_recording!(dir, id)

    users = %{
      "olga" => %{name: "olga", role: :observer, hash: "unused"},
      "ada" => %{name: "ada", role: :pilot, hash: "unused"}
    }

    secure!(@secret, users, %{anonymous_observers: true})

    bearer = fn user ->
      token = Token.sign(user, @secret, System.os_time(:second), 600)
      [{~c"authorization", ~c"Bearer " ++ String.to_charlist(token)}]
    end

    assert {401, %{"error" => "log in to delete recordings"}} =
             delete("/api/recordings/#{id}/#{old}")

    assert {403, %{"error" => error}} = delete("/api/recordings/#{id}/#{old}", bearer.("olga"))
    assert error =~ "only a pilot or the main station"
    assert File.exists?(path)
    assert {200, _} = delete("/api/recordings/#{id}/#{old}", bearer.("ada"))
    refute File.exists?(path)
  end
end
