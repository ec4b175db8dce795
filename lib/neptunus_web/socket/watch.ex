defmodule NeptunusWeb.Socket.Watch do
  @moduledoc """
  A connection's watch on the two processes its channels depend on: the PubSub scope (its
  subscriptions) and the presence server (its presences). Either may restart (see
  `Neptunus.PubSub`, "When the scope restarts"), and the new one knows nothing of the
  connection. `NeptunusWeb.Socket` keeps one per connection and calls it from the connection's
  process: it monitors, and tells the connection's channels.

  The connection watches both from its first join on (`watch/2`, for the router's `{:watch,
  msg}` effect); a join while either is restarting is refused with "server restarting: join
  again" (the client retries). On a monitor's `:DOWN` (`down/2`):

    * **the scope stopped**: the connection's subscriptions are gone and its client may have
      missed any broadcast (a `stopped`, a `helm`, a presence diff); only a rejoin gives a
      client the whole state again, so the connection closes with 1012 "service restart",
      and the phoenix client reconnects and rejoins (a pilot's channel is left like on any
      close: the helm is freed and the vehicle stops, `pilot_disconnected`);
    * **the presence server stopped**: the connection waits for the new one
      (`presence_back/2`, looking again every 20 ms) and sends each joined
      channel `:presence_restarted` (see `NeptunusWeb.Channel`): the vehicle channel tracks
      again and pushes a fresh `presence_state`.
  """
  alias Neptunus.PubSub
  alias NeptunusWeb.Presence

  # how often to look for the presence server while it restarts
  @presence_retry_ms 20

  @typedoc "The monitors of the PubSub scope and the presence server (nil: not watched)."
  @type t :: %__MODULE__{pubsub: reference() | nil, presence: reference() | nil}
  defstruct pubsub: nil, presence: nil

  @doc "Nothing watched yet (a connection before its first join)."
  @spec new() :: t()
  def new, do: %__MODULE__{}

  @doc """
  Watches the scope and the presence server, those not watched yet: `{:ok, watch}`, or
  `{:restarting, watch}` while either is down. A presence server watched anew is told to the
  connection's joined channels (`topics`; none on the first join).
  """
  @spec watch(t(), [String.t()]) :: {:ok | :restarting, t()}
  def watch(%__MODULE__{pubsub: nil} = watch, topics) do
    case PubSub.monitor() do
      {:ok, ref} -> watch(%{watch | pubsub: ref}, topics)
      {:error, :not_running} -> {:restarting, watch}
    end
  end

  def watch(%__MODULE__{presence: nil} = watch, topics) do
    case Presence.monitor() do
      {:ok, ref} -> {:ok, presence_watched(watch, ref, topics)}
      {:error, :not_running} -> {:restarting, watch}
    end
  end

  def watch(%__MODULE__{} = watch, _topics), do: {:ok, watch}

  @doc """
  What a monitor's `:DOWN` with `ref` means: `{:scope_stopped, watch}` (close with 1012),
  `{:presence_stopped, watch}` (wait for the new server: `presence_back/2`), or `:other` (not
  one of these monitors).
  """
  @spec down(t(), reference()) :: {:scope_stopped | :presence_stopped, t()} | :other
  def down(%__MODULE__{pubsub: ref} = watch, ref) when is_reference(ref),
    do: {:scope_stopped, %{watch | pubsub: nil}}

  def down(%__MODULE__{presence: ref} = watch, ref) when is_reference(ref),
    do: {:presence_stopped, %{watch | presence: nil}}

  def down(%__MODULE__{}, _ref), do: :other

  @doc """
  While the presence server is not watched: watches it if it is back, and tells the joined
  channels (`topics`) with `{:channel_info, topic, :presence_restarted}` to this process;
  otherwise looks again in #{@presence_retry_ms} ms (`:presence_back?` to this process). Once
  it is watched, nothing (a join found the new server first).
  """
  @spec presence_back(t(), [String.t()]) :: t()
  def presence_back(%__MODULE__{presence: nil} = watch, topics) do
    case Presence.monitor() do
      {:ok, ref} ->
        presence_watched(watch, ref, topics)

      {:error, :not_running} ->
        Process.send_after(self(), :presence_back?, @presence_retry_ms)
        watch
    end
  end

  def presence_back(%__MODULE__{} = watch, _topics), do: watch

  defp presence_watched(watch, ref, topics) do
    for topic <- topics, do: send(self(), {:channel_info, topic, :presence_restarted})
    %{watch | presence: ref}
  end
end
