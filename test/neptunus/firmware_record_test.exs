defmodule Neptunus.FirmwareRecordTest do
  use ExUnit.Case, async: true

  alias Neptunus.FirmwareRecord

  doctest FirmwareRecord

  @moduletag :tmp_dir

  test "reads the card's record of a rollback, with its reason", %{tmp_dir: dir} do
    path = Path.join(dir, "last-update")

    File.write!(path, """
    result=rolled-back
    version=0.2.0
    running=0.1.0
    slot=A
    reason=Neptunus 0.2.0 did not become healthy within 300s: the node is not healthy
    at=2026-11-28T08:00:00Z
    """)

    assert %{
             "result" => "rolled-back",
             "version" => "0.2.0",
             "running" => "0.1.0",
             "reason" =>
               "Neptunus 0.2.0 did not become healthy within 300s: the node is not healthy"
           } = FirmwareRecord.read(path)
  end

  test "no record: none configured, no file, an empty or foreign file", %{tmp_dir: dir} do
    assert FirmwareRecord.read(nil) == nil
    assert FirmwareRecord.read(Path.join(dir, "missing")) == nil
    File.write!(Path.join(dir, "empty"), "")
    assert FirmwareRecord.read(Path.join(dir, "empty")) == nil
    File.write!(Path.join(dir, "other"), "password=hunter2\n")
    assert FirmwareRecord.read(Path.join(dir, "other")) == nil
  end

  test "a value is cut to 500 characters" do
    assert %{"reason" => reason} = FirmwareRecord.parse("reason=" <> String.duplicate("x", 900))
    assert String.length(reason) == 500
  end
end
