defmodule Neptunus.GCS.Admission do
  @moduledoc """
  Which messages from a ground station count, and who sent them (pure): the signing rules
  of an endpoint (docs/MAVLINK.md, "Signing").

  * **Beyond loopback** every message must be signed with the key of a configured ground
    station (`NEPTUNUS_MAVLINK_GCS`). Unsigned ones are dropped (`:unsigned`); one whose
    signature fits no key is dropped (`:bad_signature`). With `NEPTUNUS_MAVLINK_UNSIGNED=watch`
    an unsigned ground station still gets the telemetry (`{:watch, identity}`), its messages
    are dropped all the same.
  * **On loopback** unsigned messages count (anyone on this computer may connect, as a
    browser may in local mode) and a signed one must fit a key.
  * **A session keeps the key it started with**: once a message signed with a key has been
    admitted, only messages signed with that key are (an unsigned one, or one signed with
    another key, is dropped): a ground station that signs cannot be spoken for by one that
    does not.
  * **Replays**: a signed message's timestamp must pass `Neptunus.Protocol.MAVLink.Signing.replay/3`
    on its stream — `{key, system, component, link id}`, shared by every session of the node,
    so a recorded message replayed from another address is refused as well
    (`Neptunus.GCS.Replay` keeps the streams).

  The identity of an admitted message's session: a signed one is its key's ground station
  (name and role); an unsigned one on loopback is `gcs-<system id>`, a pilot in local mode and
  an observer in secure mode. `trusted` (it may take a free helm by flying): local mode, a
  loopback endpoint and a system id of `NEPTUNUS_MAVLINK_TRUSTED`.
  """

  alias Neptunus.Protocol.MAVLink.{Message, Signing}

  @type config :: %{
          keys: %{String.t() => %{name: String.t(), role: atom(), key: binary()}},
          loopback: boolean(),
          mode: :local | :secure,
          trusted: [1..255],
          unsigned: :none | :watch
        }

  @type stream :: {String.t(), byte(), byte(), byte()}
  @type verdict ::
          {:unsigned, Neptunus.GCS.Session.identity()}
          | {:signed, String.t(), stream(), Signing.timestamp()}
          | {:watch, Neptunus.GCS.Session.identity()}
          | {:drop, :unsigned | :bad_signature}

  @doc """
  What to do with `message` on a session bound to key `bound` (nil: none yet): count it as
  unsigned, check its stream's replay and count it as signed by a key, let the session watch,
  or drop it and why.
  """
  @spec check(config(), String.t() | nil, Message.t()) :: verdict()
  def check(config, bound, %Message{signature: nil} = message) do
    cond do
      bound != nil -> {:drop, :unsigned}
      config.loopback -> {:unsigned, unsigned_identity(config, message.system)}
      config.unsigned == :watch -> {:watch, watcher()}
      true -> {:drop, :unsigned}
    end
  end

  def check(config, bound, %Message{signature: signature} = message) do
    candidates =
      case bound do
        nil -> Map.values(config.keys)
        name -> Enum.filter([config.keys[name]], & &1)
      end

    case Enum.find(candidates, &Signing.verify(message, &1.key)) do
      nil ->
        {:drop, :bad_signature}

      key ->
        stream = {key.name, message.system, message.component, signature.link_id}
        {:signed, key.name, stream, signature.timestamp}
    end
  end

  @doc "The identity of a session signed with key `name` by ground station `sysid`."
  @spec signed_identity(config(), String.t(), byte()) :: Neptunus.GCS.Session.identity()
  def signed_identity(config, name, sysid) do
    key = Map.fetch!(config.keys, name)
    %{name: key.name, role: key.role, trusted: trusted?(config, sysid)}
  end

  @doc "The identity of an unsigned ground station `sysid` on a loopback endpoint."
  @spec unsigned_identity(config(), byte()) :: Neptunus.GCS.Session.identity()
  def unsigned_identity(config, sysid) do
    role = if config.mode == :local, do: :pilot, else: :observer
    %{name: "gcs-#{sysid}", role: role, trusted: trusted?(config, sysid)}
  end

  @doc "The identity of an unsigned ground station let watch (it flies nothing)."
  @spec watcher() :: Neptunus.GCS.Session.identity()
  def watcher, do: %{name: "unsigned", role: :observer, trusted: false}

  defp trusted?(config, sysid),
    do: config.mode == :local and config.loopback and sysid in config.trusted
end
