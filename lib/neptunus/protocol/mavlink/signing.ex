defmodule Neptunus.Protocol.MAVLink.Signing do
  @moduledoc """
  MAVLink 2 message signing (the spec's "Message Signing"): signing a frame, verifying a
  signed message, the timestamp, and the replay rule. Pure.

  A signed frame has the incompatibility flag 0x01 and 13 bytes after its checksum: the link
  id (1 byte), a timestamp (48 bits, little-endian, in 10 µs since 2015-01-01 00:00 UTC) and
  the signature: the first 48 bits of

      SHA-256(secret_key ‖ frame from the start byte to the checksum ‖ link id ‖ timestamp)

  with a 32-byte secret key shared out of band. Ground stations derive the key from a
  passphrase as its SHA-256 (MAVProxy's `signing key PASSPHRASE`; `key_from_passphrase/1`).

  ## Timestamps and replays

  A sender's timestamps grow on every frame it sends on a link (`next_timestamp/2`: the
  clock's, or one more than the last when the clock has not moved on). A receiver keeps, for
  every stream — the sender's `{system, component, link id}` under one key — the last
  timestamp it accepted, and `replay/3` decides on the next one: a known stream must go
  forward (`:replayed` otherwise); a new stream must not be more than a minute behind the
  receiver's clock (`:too_old`), so a frame recorded earlier cannot open a stream later.
  """

  import Bitwise

  alias Neptunus.Protocol.MAVLink.Message

  # 2015-01-01 00:00:00 UTC in Unix microseconds
  @epoch_us 1_420_070_400_000_000
  # a new stream may start at most a minute behind our clock (in 10 µs units)
  @window 6_000_000
  @max_timestamp (1 <<< 48) - 1

  @type key :: <<_::256>>
  @type timestamp :: 0..281_474_976_710_655

  @doc """
  The signing timestamp of a Unix time in microseconds (10 µs units since 2015-01-01).

      iex> Neptunus.Protocol.MAVLink.Signing.timestamp(1_420_070_400_000_000 + 25)
      2
  """
  @spec timestamp(integer()) :: timestamp()
  def timestamp(unix_us) when is_integer(unix_us),
    do: min(max(div(unix_us - @epoch_us, 10), 0), @max_timestamp)

  @doc """
  The timestamp of the next frame a link sends: the clock's `now`, or one more than the
  `last` one sent when the clock has not moved past it.

      iex> Neptunus.Protocol.MAVLink.Signing.next_timestamp(100, 90)
      100
      iex> Neptunus.Protocol.MAVLink.Signing.next_timestamp(100, 100)
      101
  """
  @spec next_timestamp(timestamp(), timestamp()) :: timestamp()
  def next_timestamp(now, last), do: min(max(now, last + 1), @max_timestamp)

  @doc """
  The 32-byte key a ground station derives from a passphrase (SHA-256 of its bytes), as
  MAVProxy's `signing key` and QGroundControl do.
  """
  @spec key_from_passphrase(String.t()) :: key()
  def key_from_passphrase(passphrase) when is_binary(passphrase),
    do: :crypto.hash(:sha256, passphrase)

  @doc """
  Signs an unsigned MAVLink 2 `frame` (as `Neptunus.Protocol.MAVLink.encode/4` makes it),
  stamping sequence number `seq`: sets the signed flag, recomputes the checksum and appends
  link id, timestamp and signature.
  """
  @spec sign(binary(), byte(), key(), byte(), timestamp()) :: binary()
  def sign(frame, seq, key, link_id, timestamp)
      when byte_size(key) == 32 and link_id in 0..255 and timestamp in 0..@max_timestamp do
    signed = [
      Neptunus.Protocol.MAVLink.restamp(frame, seq, 1),
      <<link_id, timestamp::little-48>>
    ]

    bytes = IO.iodata_to_binary(signed)
    <<bytes::binary, signature(key, bytes)::binary>>
  end

  @doc "The 48-bit signature of `signed` (a frame up to and including its timestamp)."
  @spec signature(key(), iodata()) :: <<_::48>>
  def signature(key, signed) do
    <<signature::binary-size(6), _::binary>> = :crypto.hash(:sha256, [key, signed])
    signature
  end

  @doc """
  Whether a decoded `message`'s signature is right for `key` (compared in constant time).
  An unsigned message is not.
  """
  @spec verify(Message.t(), key()) :: boolean()
  def verify(%Message{signature: %{signature: signature, signed: signed}}, key)
      when byte_size(key) == 32,
      do: :crypto.hash_equals(signature(key, signed), signature)

  def verify(%Message{}, _key), do: false

  @doc """
  Whether a signed frame's `timestamp` may be accepted on a stream whose last accepted
  timestamp is `last` (nil: a new stream), with the receiver's clock at `now` (in signing
  units): `:ok`, `{:error, :replayed}` (not after the last) or `{:error, :too_old}` (a new
  stream more than a minute behind).

      iex> Neptunus.Protocol.MAVLink.Signing.replay(10, 11, 0)
      :ok
      iex> Neptunus.Protocol.MAVLink.Signing.replay(10, 10, 0)
      {:error, :replayed}
      iex> Neptunus.Protocol.MAVLink.Signing.replay(nil, 1, 6_000_002)
      {:error, :too_old}
  """
  @spec replay(timestamp() | nil, timestamp(), timestamp()) ::
          :ok | {:error, :replayed | :too_old}
  def replay(nil, timestamp, now) when timestamp + @window < now, do: {:error, :too_old}
  def replay(nil, _timestamp, _now), do: :ok
  def replay(last, timestamp, _now) when timestamp > last, do: :ok
  def replay(_last, _timestamp, _now), do: {:error, :replayed}
end
