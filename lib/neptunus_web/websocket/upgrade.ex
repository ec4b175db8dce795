defmodule NeptunusWeb.WebSocket.Upgrade do
  @moduledoc """
  The upgrade of an HTTP request to a WebSocket, for every WebSocket endpoint of the node: who
  may open one, and yaws' answer. `NeptunusWeb.Socket` (the Channels socket) upgrades through
  here, and so does any other WebSocket endpoint, so that all of them let in exactly the same
  people:

      # in the yaws appmod's out/1, after checking its own path and parameters
      Upgrade.upgrade(arg, __MODULE__, %{vehicle: id}, hibernate_after: 1_000)

  The request is authorised by `NeptunusWeb.Auth.connect/1` from its `Origin` and `Host`
  headers and its `token` and `name` query parameters: a foreign `Origin` (or, in local
  mode, `Host`) is refused with 403, a missing, invalid or expired token in secure mode with
  401 (unless anonymous observers are allowed), each as `{"error": reason}`. Who may
  *command* is not decided here: the vehicle's helm decides that for each command.

  The handler is a yaws WebSocket callback module in basic mode (`init/1`, `handle_open/2`,
  `handle_message/2`, `handle_info/2`, `terminate/2`); its `init([arg, state])` gets the
  state given here with the connection's `user` (`t:NeptunusWeb.Auth.user/0`) added. yaws
  closes with 1011 and logs nothing when a callback raises: guard the bodies. To send a
  broadcast's shared binary without a copy per connection, see
  `NeptunusWeb.WebSocket.Transport`.
  """
  import NeptunusWeb.Endpoint.Yaws

  alias NeptunusWeb.Auth

  @typedoc "What a yaws appmod's `out/1` returns."
  @type out ::
          {:websocket, module(), [tuple()]}
          | [{:status, pos_integer()} | {:content, charlist(), iodata()}]

  @doc """
  Authorises the WebSocket upgrade `arg` (yaws' `#arg{}`): the connection's user, or the
  HTTP status and reason to refuse it with (see the moduledoc).
  """
  @spec authorize(tuple()) :: {:ok, Auth.user()} | {:error, 401 | 403, String.t()}
  def authorize(arg) do
    headers = arg(arg, :headers)
    params = query(arg)

    Auth.connect(%{
      origin: header(headers, "origin"),
      host: text(headers(headers, :host)),
      token: params["token"],
      name: params["name"]
    })
  end

  @doc """
  yaws' answer to the upgrade request `arg`: the WebSocket, run by `handler` with `state`
  (a map; the connection's `user` is added) and yaws' WebSocket `options` (such as
  `hibernate_after`, `max_frame_size`, `max_message_size`), when `authorize/1` lets it in;
  the refusal otherwise (`refuse/2`).
  """
  @spec upgrade(tuple(), module(), map(), keyword()) :: out()
  def upgrade(arg, handler, state \\ %{}, options \\ [])
      when is_atom(handler) and is_map(state) and is_list(options) do
    case authorize(arg) do
      {:ok, user} ->
        {:websocket, handler, [{:callback, {:basic, Map.put(state, :user, user)}} | options]}

      {:error, status, reason} ->
        refuse(status, reason)
    end
  end

  @doc "The answer that refuses an upgrade: `status` with `{\"error\": reason}`."
  @spec refuse(pos_integer(), String.t()) :: out()
  def refuse(status, reason) do
    [{:status, status}, {:content, ~c"application/json", Neptunus.JSON.encode!(%{error: reason})}]
  end
end
