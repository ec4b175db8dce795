defmodule Neptunus.Protocol.MAVLink.Message do
  @moduledoc """
  A decoded MAVLink message: the message's id and name, the sender's system and component ids,
  the frame's sequence number, the protocol version it came in (1 or 2), its fields as MAVLink
  defines them (raw values: integers, floats or `:nan` / `:infinity` / `:neg_infinity`, strings
  as binaries without their NUL padding, arrays as lists, enums and bitmasks as integers), and
  the signature of a signed MAVLink 2 frame (`nil` when unsigned; the decoder does not verify
  it: `Neptunus.Protocol.MAVLink.Signing.verify/2` does).

  The signature is `%{link_id: 0..255, timestamp: integer, signature: <<_::48>>, signed:
  binary}`, the timestamp in the spec's units (10 µs since 2015-01-01 00:00 UTC), `signed` the
  bytes the signature covers (the frame from its start byte up to the timestamp).
  """

  @enforce_keys [:id, :name, :system, :component, :seq, :version, :fields]
  defstruct [:id, :name, :system, :component, :seq, :version, :fields, signature: nil]

  @type value :: integer() | float() | :nan | :infinity | :neg_infinity | binary() | [value()]
  @type signature :: %{
          link_id: byte(),
          timestamp: non_neg_integer(),
          signature: binary(),
          signed: binary()
        }
  @type t :: %__MODULE__{
          id: non_neg_integer(),
          name: atom(),
          system: byte(),
          component: byte(),
          seq: byte(),
          version: 1 | 2,
          fields: %{atom() => value()},
          signature: signature() | nil
        }
end
