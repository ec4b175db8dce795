defmodule Neptunus.PubSub.Follow do
  @retry_ms 20

  @moduledoc """
  A long-lived subscriber's hold on its topics across restarts of the PubSub scope (see
  `Neptunus.PubSub`, "When the scope restarts"): the one recipe for "subscribe, watch the
  scope, and when it goes down subscribe again once it is back".

  The process keeps a follow in its state and passes it every `{:DOWN, …}` and every
  `t:retry/0` it receives; `subscribe/1` and `handle/2` say what happened, so the process
  can add what is its own (the recorder says how long it was unsubscribed, a ground station
  source reads the vehicle's state again):

      def init(id), do: {:ok, %State{follow: Follow.new([topic(id)])}, {:continue, :subscribe}}

      def handle_continue(:subscribe, state) do
        {_subscribed_or_waiting, follow} = Follow.subscribe(state.follow)
        {:noreply, %{state | follow: follow}}
      end

      def handle_info({:DOWN, _, :process, _, _} = msg, state), do: follow(state, msg)
      def handle_info({Follow, :retry, _} = msg, state), do: follow(state, msg)

      defp follow(state, msg) do
        {_event, follow} = Follow.handle(state.follow, msg)
        {:noreply, %{state | follow: follow}}
      end

  The events:

    * `:subscribed`: subscribed to every topic, the scope watched (what was broadcast
      meanwhile is lost);
    * `:waiting`: the scope is down or restarting; the follow tries again in #{@retry_ms} ms (a
      `t:retry/0` to the process);
    * `:lost`: the scope stopped and the subscriptions went with it; the follow tries again
      at once (a `t:retry/0` to the process);
    * `:other`: not this follow's message (another monitor's `:DOWN`), or a retry it no
      longer needs; the follow is unchanged.

  A process that subscribes only for a while (a camera while it renders) ends its follow
  with `unsubscribe/1`, and may subscribe it again later.

  While it follows, a follow has either the scope's monitor or a retry on its way, never
  both; a process may hold several follows (of different topics).
  """

  alias Neptunus.PubSub

  @typedoc """
  The topics followed, and where the follow is: subscribed (the scope's monitor), `:waiting`
  (a retry on its way) or not following (nil: new, or unsubscribed).
  """
  @type t :: %__MODULE__{topics: [PubSub.topic()], scope: reference() | :waiting | nil}
  @enforce_keys [:topics]
  defstruct [:topics, scope: nil]

  @typedoc "The message a follow sends its process to subscribe again."
  @type retry :: {__MODULE__, :retry, [PubSub.topic()]}

  @type event :: :subscribed | :waiting | :lost | :other

  @doc """
  A follow of `topics`, not subscribed yet (pure).

      iex> follow = Neptunus.PubSub.Follow.new(["vehicle:rov"])
      iex> Neptunus.PubSub.Follow.subscribed?(follow)
      false
  """
  @spec new([PubSub.topic()]) :: t()
  def new(topics) when is_list(topics), do: %__MODULE__{topics: topics}

  @doc "Whether the follow is subscribed (it has the scope's monitor)."
  @spec subscribed?(t()) :: boolean()
  def subscribed?(%__MODULE__{scope: scope}), do: is_reference(scope)

  @doc """
  Subscribes the calling process with a follow that is not following (`new/1`,
  `unsubscribe/1`; while it follows, `handle/2` subscribes again), through
  `Neptunus.PubSub.follow/1`: `{:subscribed, follow}`, or `{:waiting, follow}` with a retry
  in #{@retry_ms} ms.
  """
  @spec subscribe(t()) :: {:subscribed | :waiting, t()}
  def subscribe(%__MODULE__{scope: nil} = follow), do: attempt(follow)

  defp attempt(follow) do
    case PubSub.follow(follow.topics) do
      {:ok, ref} ->
        {:subscribed, %{follow | scope: ref}}

      {:error, :not_running} ->
        Process.send_after(self(), retry(follow), @retry_ms)
        {:waiting, %{follow | scope: :waiting}}
    end
  end

  @doc """
  Ends the follow: the calling process unsubscribes from its topics and no longer watches the
  scope; a retry on its way will change nothing.
  """
  @spec unsubscribe(t()) :: t()
  def unsubscribe(%__MODULE__{} = follow) do
    if is_reference(follow.scope), do: Process.demonitor(follow.scope, [:flush])
    Enum.each(follow.topics, &PubSub.unsubscribe/1)
    %{follow | scope: nil}
  end

  @doc """
  What `message` means to the follow (see the events above), with the follow after it: the
  scope's `:DOWN` is `:lost`; its retry `:subscribed` or `:waiting`; anything else `:other`.
  """
  @spec handle(t(), term()) :: {event(), t()}
  def handle(%__MODULE__{scope: ref} = follow, {:DOWN, ref, :process, _pid, _reason})
      when is_reference(ref) do
    follow = %{follow | scope: :waiting}
    send(self(), retry(follow))
    {:lost, follow}
  end

  def handle(%__MODULE__{scope: :waiting, topics: topics} = follow, {__MODULE__, :retry, topics}),
    do: attempt(follow)

  def handle(%__MODULE__{} = follow, _message), do: {:other, follow}

  defp retry(follow), do: {__MODULE__, :retry, follow.topics}
end
