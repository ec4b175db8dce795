defmodule NeptunusWeb.Channel do
  @moduledoc """
  The behaviour of a channel: the server side of one topic joined on one WebSocket.

  Channels run inside their connection's process (`NeptunusWeb.Socket`): a message from the
  browser is a function call away from the vehicle, and an exception in a channel is caught
  by the socket, reported to the client as `phx_error` for that topic, and leaves the other
  channels of the connection alone.

  The socket subscribes the connection to the channel's topic on join (broadcasts reach the
  browser pre-encoded, see `Neptunus.PubSub`) and unsubscribes on leave.

  A channel sends itself a message with `send_self/2`; it arrives in `c:handle_info/2`.
  The socket sends every joined channel `:presence_restarted` there when the presence
  server (`NeptunusWeb.Presence`) has restarted and forgotten the connection's presences: a
  channel that tracks presences tracks them again and pushes a fresh `presence_state`.
  """

  defmodule Socket do
    @moduledoc "A joined channel's state: topic, join ref, the connection's user, assigns."
    @type t :: %__MODULE__{
            topic: String.t(),
            join_ref: String.t() | nil,
            user: NeptunusWeb.Auth.user(),
            transport_pid: pid(),
            assigns: map()
          }
    @enforce_keys [:topic, :user, :transport_pid]
    defstruct [:topic, :join_ref, :user, :transport_pid, assigns: %{}]
  end

  @type reply :: {:ok | :error, map()}

  @doc "Join `topic` with the client's payload. `{:error, %{reason: ...}}` refuses."
  @callback join(topic :: String.t(), payload :: map(), Socket.t()) ::
              {:ok, reply :: map(), Socket.t()} | {:error, reply :: map()}

  @doc "An event pushed by the client. Every push gets a reply."
  @callback handle_in(event :: String.t(), payload :: map(), Socket.t()) ::
              {:reply, reply(), Socket.t()}

  @doc "A message sent with `send_self/2`; may push an event to this client."
  @callback handle_info(msg :: term(), Socket.t()) ::
              {:noreply, Socket.t()} | {:push, event :: String.t(), payload :: map(), Socket.t()}

  @doc "The channel is left (client leave, rejoin, or connection closed)."
  @callback terminate(reason :: term(), Socket.t()) :: term()

  @doc "Sends `msg` to this channel's `c:handle_info/2`, after the current callback."
  @spec send_self(Socket.t(), term()) :: :ok
  def send_self(%Socket{topic: topic, transport_pid: pid}, msg) do
    send(pid, {:channel_info, topic, msg})
    :ok
  end

  @doc "Merges `assigns` into the socket's assigns."
  @spec assign(Socket.t(), map() | keyword()) :: Socket.t()
  def assign(%Socket{} = socket, assigns),
    do: %{socket | assigns: Enum.into(assigns, socket.assigns)}
end
