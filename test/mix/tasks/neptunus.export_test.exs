defmodule Mix.Tasks.Neptunus.ExportTest do
  # `mix neptunus.export VEHICLE/DIVE --format … --out FILE`: a dive folder exported by the
  # task is what the real readers (ffprobe, the mcap package) read, the CSV is the API's; bad
  # input stops the task with a message and writes nothing.
  use ExUnit.Case, async: true

  import ExUnit.CaptureIO

  alias Mix.Tasks.Neptunus.Export, as: Task
  alias Neptunus.Dive
  alias Neptunus.Dive.Export
  alias Neptunus.Test.Dives

  @moduletag :tmp_dir
  @vehicle "rov-t"
  @name "20261128-100000Z-1"
  @start_ms 1_795_000_000_000

  # 2 s of a 15 fps camera and 2.5 s of telemetry at 20 Hz
  defp dive!(dir) do
    frames =
      Dives.h264(30, fps: 15, gop: 15)
      |> Enum.with_index()
      |> Enum.map(fn {au, i} ->
        {@start_ms * 1000 + i * div(1_000_000, 15), Dives.keyframe?(au), au}
      end)

    entries = Dives.telemetry(@start_ms - 200, 50)
    Dives.write!(dir, @vehicle, @name, entries, frames, started_at: @start_ms - 200)
    {entries, frames}
  end

  defp export(dir, args) do
    capture_io(fn -> Task.run(["#{@vehicle}/#{@name}", "--dir", dir] ++ args) end)
  end

  test "MP4, MCAP and CSV, as their readers read them", %{tmp_dir: dir} do
    {entries, frames} = dive!(dir)

    mp4 = Path.join(dir, "out.mp4")
    assert export(dir, ~w(--format mp4 --out) ++ [mp4]) =~ "out.mp4: "

    {out, 0} =
      System.cmd(
        "ffprobe",
        ~w(-v error -count_frames -show_entries
                                stream=codec_type,nb_read_frames -of csv=p=0) ++ [mp4]
      )

    assert "video,#{length(frames)}" in String.split(out, "\n", trim: true)

    mcap = Path.join(dir, "out.mcap")
    export(dir, ~w(--format mcap --out) ++ [mcap])
    read = Dives.mcap_read!(mcap)
    assert read["topics"]["/vehicle/telemetry"]["count"] == length(entries)
    assert read["topics"]["/camera"]["count"] == length(frames)

    csv = Path.join(dir, "out.csv")
    export(dir, ~w(--format csv --out) ++ [csv])
    folder = Dive.path(dir, @vehicle, @name)
    {:ok, plan} = Export.plan(folder, "x", %{"format" => "csv"})
    assert File.read!(csv) == plan |> Export.stream() |> Enum.to_list() |> IO.iodata_to_binary()

    assert csv |> File.read!() |> String.split("\n", trim: true) |> length() ==
             1 + length(entries)

    # only the exports are left: the temporary files were renamed
    assert dir |> File.ls!() |> Enum.sort() == ["out.csv", "out.mcap", "out.mp4", @vehicle]
  end

  test "bad input stops with a message and writes nothing", %{tmp_dir: dir} do
    dive!(dir)
    out = Path.join(dir, "out.csv")
    dive = "#{@vehicle}/#{@name}"

    for {args, message} <- [
          {[], "usage: mix neptunus.export VEHICLE/DIVE"},
          {[dive, "--out", out], "--format is required"},
          {[dive, "--format", "csv"], "--out FILE is required"},
          {[dive, "--format", "csv", "--out", out, "--speed", "2"],
           "unknown or invalid option --speed"},
          {[@name, "--format", "csv", "--out", out, "--dir", dir], "DIVE must be VEHICLE/DIVE"},
          {[dive, "--format", "avi", "--out", out, "--dir", dir],
           ~s(--format must be one of csv, jsonl, ass, mp4, mcap, got "avi")},
          {[dive, "--format", "csv", "--out", out, "--dir", Path.join(dir, "nope")],
           "the recordings folder #{dir}/nope does not exist"},
          {["rov x/#{@name}", "--format", "csv", "--out", out, "--dir", dir],
           "VEHICLE must be a vehicle id"},
          {["rov-u/#{@name}", "--format", "csv", "--out", out, "--dir", dir],
           "no recordings of vehicle rov-u in #{dir} (vehicles there: #{@vehicle})"},
          {["#{@vehicle}/20261128-100000Z-2", "--format", "csv", "--out", out, "--dir", dir],
           "no such dive: #{@vehicle}/20261128-100000Z-2 in #{dir} (dives there: #{@name})"},
          {["#{@vehicle}/..", "--format", "csv", "--out", out, "--dir", dir], "no such dive"},
          {[dive, "--format", "csv", "--out", Path.join([dir, "no", "x.csv"]), "--dir", dir],
           "the folder #{dir}/no does not exist"},
          {[dive, "--format", "csv", "--out", dir, "--dir", dir], "is a folder"}
        ] do
      error = assert_raise Mix.Error, fn -> capture_io(fn -> Task.run(args) end) end
      assert error.message =~ message, "#{inspect(args)}: #{error.message}"
    end

    assert File.ls!(dir) == [@vehicle]
  end

  test "a dive without video: no MP4, and why", %{tmp_dir: dir} do
    Dives.write!(dir, @vehicle, @name, Dives.telemetry(@start_ms, 10), [])
    out = Path.join(dir, "out.mp4")

    error =
      assert_raise Mix.Error, fn ->
        export(dir, ~w(--format mp4 --out) ++ [out])
      end

    assert error.message =~ "this dive has no video"
    refute File.exists?(out)
  end
end
