defmodule Neptunus.Protocol.MAVLink.Decoder do
  @moduledoc """
  The state of a streaming MAVLink decoder (`Neptunus.Protocol.MAVLink.decode/2`): the start
  of a frame that has not fully arrived yet (at most the longest frame, 280 bytes),
  the last sequence number seen from each sender, and the counters.

  `stats` counts, since the decoder was made: `messages` decoded, `garbage_bytes` skipped while
  looking for a frame (including the start byte of each frame dropped for a bad checksum or an
  unsupported incompatibility flag), `bad_checksum` frames, `unknown` frames (message ids
  without a definition, skipped by their length) and `lost` frames (gaps in the senders'
  sequence numbers). `sources` has, per sender `{system, component}`, the frames `received`
  (known and unknown ids), the frames `lost` and the `last_seq`.
  """

  defstruct buffer: <<>>,
            stats: %{messages: 0, garbage_bytes: 0, bad_checksum: 0, unknown: 0, lost: 0},
            sources: %{}

  @type source :: {byte(), byte()}
  @type stats :: %{
          messages: non_neg_integer(),
          garbage_bytes: non_neg_integer(),
          bad_checksum: non_neg_integer(),
          unknown: non_neg_integer(),
          lost: non_neg_integer()
        }
  @type t :: %__MODULE__{
          buffer: binary(),
          stats: stats(),
          sources: %{
            source() => %{received: pos_integer(), lost: non_neg_integer(), last_seq: byte()}
          }
        }
end
