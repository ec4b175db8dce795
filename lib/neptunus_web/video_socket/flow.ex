defmodule NeptunusWeb.VideoSocket.Flow do
  @moduledoc """
  Which frames a video viewer gets (pure): `NeptunusWeb.VideoSocket` asks for each frame
  the camera publishes, with the number of messages waiting in its mailbox, and sends or
  drops it as told.

    * A viewer starts at a keyframe: after it joins, after a new stream (generation) began,
      and after it asked for one (`{"event": "keyframe"}`, e.g. after a decoder error), the
      frames before the next keyframe are dropped — a decoder could not use them.
    * A viewer that falls behind — `backlog` or more messages wait for it: its client reads
      slower than the camera sends (a weak link, a busy tablet) — drops whole groups of
      pictures: every frame until a keyframe arrives while fewer than `backlog` wait. It
      then gets `{:skipped, n}` (tell the client, `skipped` message) and the keyframe, and
      is at the live edge again. Its backlog is its own: the camera and every other viewer
      go on at their pace (the socket's send timeout ends a client that reads nothing).

      iex> alias NeptunusWeb.VideoSocket.Flow
      iex> flow = Flow.new(backlog: 4)
      iex> {flow, :drop} = Flow.frame(flow, false, 0)
      iex> {flow, :send} = Flow.frame(flow, true, 0)
      iex> {flow, :send} = Flow.frame(flow, false, 3)
      iex> {flow, :drop} = Flow.frame(flow, false, 4)
      iex> {flow, :drop} = Flow.frame(flow, true, 6)
      iex> {flow, {:skipped, 2}} = Flow.frame(flow, true, 0)
      iex> {flow.sent, flow.dropped}
      {3, 2}
  """

  @typedoc """
  * `backlog` — waiting messages from which on the viewer is behind
  * `keyframe?` — frames wait for a keyframe (a start, a new stream, a request)
  * `skipping` — frames are dropped until a keyframe, for a viewer behind; `skipped` counts
    them
  * `sent`, `dropped` — frames sent, and dropped for being behind, since the start
  """
  @type t :: %__MODULE__{
          backlog: pos_integer(),
          keyframe?: boolean(),
          skipping: boolean(),
          skipped: non_neg_integer(),
          sent: non_neg_integer(),
          dropped: non_neg_integer()
        }
  @enforce_keys [:backlog]
  defstruct [:backlog, keyframe?: true, skipping: false, skipped: 0, sent: 0, dropped: 0]

  @type verdict :: :send | :drop | {:skipped, pos_integer()}

  @doc "A new viewer, waiting for a keyframe. Option `backlog` (a positive integer)."
  @spec new(keyword()) :: t()
  def new(opts) do
    case Keyword.fetch(opts, :backlog) do
      {:ok, n} when is_integer(n) and n > 0 -> %__MODULE__{backlog: n}
      other -> raise ArgumentError, "backlog must be a positive integer, got #{inspect(other)}"
    end
  end

  @doc "A new stream began, or the client asked for a keyframe: wait for the next one."
  @spec await_keyframe(t()) :: t()
  def await_keyframe(%__MODULE__{} = flow), do: %{flow | keyframe?: true}

  @doc """
  Decides a frame (`keyframe?`) while `waiting` messages wait for the viewer: `:send`,
  `:drop`, or `{:skipped, n}` — send it after telling the client that `n` frames were
  dropped for being behind.
  """
  @spec frame(t(), boolean(), non_neg_integer()) :: {t(), verdict()}
  def frame(%__MODULE__{} = flow, keyframe?, waiting)
      when is_boolean(keyframe?) and is_integer(waiting) and waiting >= 0 do
    behind? = waiting >= flow.backlog

    cond do
      flow.skipping and keyframe? and not behind? ->
        {%{flow | skipping: false, skipped: 0, keyframe?: false, sent: flow.sent + 1},
         {:skipped, flow.skipped}}

      flow.skipping ->
        {%{flow | skipped: flow.skipped + 1, dropped: flow.dropped + 1}, :drop}

      flow.keyframe? and keyframe? ->
        {%{flow | keyframe?: false, sent: flow.sent + 1}, :send}

      flow.keyframe? ->
        {flow, :drop}

      behind? ->
        {%{flow | skipping: true, skipped: 1, dropped: flow.dropped + 1}, :drop}

      true ->
        {%{flow | sent: flow.sent + 1}, :send}
    end
  end
end
