defmodule Neptunus.GCS.AdmissionTest do
  use ExUnit.Case, async: true

  alias Neptunus.GCS.Admission
  alias Neptunus.Protocol.MAVLink
  alias Neptunus.Protocol.MAVLink.Signing

  @qgc Signing.key_from_passphrase("qgc passphrase")
  @main Signing.key_from_passphrase("topside passphrase")
  @keys %{
    "qgc" => %{name: "qgc", role: :pilot, key: @qgc},
    "topside" => %{name: "topside", role: :main_station, key: @main}
  }

  defp config(opts),
    do:
      Map.merge(
        %{keys: @keys, loopback: true, mode: :local, trusted: [], unsigned: :none},
        Map.new(opts)
      )

  defp message(key \\ nil, sysid \\ 255, ts \\ 1_000) do
    {:ok, frame} =
      MAVLink.encode(
        :heartbeat,
        %{type: 6, autopilot: 8, base_mode: 0, custom_mode: 0, system_status: 4},
        %{system: sysid, component: 190, seq: 0}
      )

    frame = if key, do: Signing.sign(frame, 0, key, 3, ts), else: frame
    {_, [m], []} = MAVLink.decode(MAVLink.new(), frame)
    m
  end

  test "beyond loopback: unsigned dropped (or let watch), a key's signature names its ground station" do
    far = config(loopback: false)
    assert Admission.check(far, nil, message()) == {:drop, :unsigned}

    assert {:watch, %{role: :observer}} =
             Admission.check(config(loopback: false, unsigned: :watch), nil, message())

    assert {:signed, "qgc", {"qgc", 255, 190, 3}, 1_000} =
             Admission.check(far, nil, message(@qgc))

    assert {:signed, "topside", _, _} = Admission.check(far, nil, message(@main))

    assert Admission.check(far, nil, message(Signing.key_from_passphrase("guess"))) ==
             {:drop, :bad_signature}
  end

  test "a session keeps its key: another key's or an unsigned message is dropped" do
    assert Admission.check(config([]), "qgc", message(@main)) == {:drop, :bad_signature}
    assert Admission.check(config([]), "qgc", message()) == {:drop, :unsigned}
    assert {:signed, "qgc", _, _} = Admission.check(config([]), "qgc", message(@qgc))
  end

  test "on loopback unsigned counts: a pilot in local mode, an observer in secure mode; trusted ids" do
    assert {:unsigned, %{name: "gcs-255", role: :pilot, trusted: false}} =
             Admission.check(config([]), nil, message())

    assert {:unsigned, %{role: :observer}} =
             Admission.check(config(mode: :secure), nil, message())

    assert {:unsigned, %{trusted: true}} = Admission.check(config(trusted: [255]), nil, message())

    assert {:unsigned, %{trusted: false}} =
             Admission.check(config(trusted: [255], mode: :secure), nil, message())

    assert {:unsigned, %{trusted: false}} =
             Admission.check(config(trusted: [250]), nil, message())
  end

  test "identities of signed sessions" do
    assert %{name: "topside", role: :main_station, trusted: false} =
             Admission.signed_identity(config([]), "topside", 255)

    assert %{trusted: false} =
             Admission.signed_identity(config(loopback: false, trusted: [255]), "qgc", 255)
  end
end
