defmodule Neptunus.Helm.Policy do
  @moduledoc """
  Who is in control of a vehicle: the helm's decisions as a pure function
  `handle(policy, event, now) -> {reply, policy, actions}`. `Neptunus.Vehicle.Helm` runs it
  and carries out the actions; nothing here sends, waits or reads a clock.

  ## States (`t:helm/0`)

    * `:free` — nobody pilots; the thrusters are neutral.
    * `{:piloted, pilot}` — one party pilots, everyone else watches.
    * `{:requested, pilot, requester}` — `requester` asked for control and `pilot` has been
      asked (one request at a time; the process adds the request timeout).
    * `{:takeover, pilot, main}` — the main station takes control without acknowledge; both
      are warned and the transfer happens when the countdown ends (`:takeover_due`).

  A *party* is one connection of a user: `%{id, name, role}` (plus whatever the process keeps
  in it, e.g. the pid). Parties are told apart by `id` alone, so the same user on two
  connections is two parties and the deadman only counts the pilot connection's own messages.

  ## Events (`t:event/0`)

  `{:request, p}`, `{:answer, p, accept?}`, `{:take, p}`, `{:release, p}`, `{:heartbeat, p}`,
  `{:command, p, stamp}`, `{:leave, id, reason}` (connection closed or channel left),
  `:request_timeout`, `:takeover_due` and `{:tick, deadman_ms}` (deadman check). `now` is
  the vehicle's monotonic clock in ms (injected, so the deadman is testable).

  ## Pick-up procedure and command stamps

  Every grant (and every deadman trip) increments `epoch` (starting from `new/1`'s value). The grant tells the new pilot the
  epoch, and stamped commands (`{:command, p, {:epoch, e}}`, e.g. thrust) run only when `e`
  is the current epoch: a command the client made before it learnt of its grant — a stale
  stick, or a push the client buffered while it was not joined — is refused with
  `stale_command`. Unstamped commands (`{:command, p, :none}`, e.g. stop) only need `p` to
  be the pilot. Every transfer stops the thrusters first.

  ## Deadman

  Each message of the pilot (`heartbeat`, commands, answers, requests) refreshes
  `last_seen_ms`. On `{:tick, deadman_ms}` a pilot silent for longer than `deadman_ms` trips the
  deadman once: stop with reason `deadman`, a new epoch (so commands made before the client
  heard of the trip are stale and thrust stays neutral until a fresh command). The pilot
  keeps the helm; its next command that runs (a fresh thrust, a stop) re-arms the deadman —
  heartbeats alone do not, so a pilot that only heartbeats now and then is stopped once, not
  every time it falls silent again.

  ## Actions (`t:action/0`)

    * `{:stop, reason}` — thrusters neutral, `stopped` broadcast with `reason`;
    * `{:grant, party}` — `party` is the new pilot (send it the grant);
    * `{:revoke, party, reason}` — `party` lost the helm;
    * `{:push, party, event, payload}` — an event for one party only
      (`control_request` to the pilot, `request_denied` to a requester);
    * `:changed` — the helm changed: broadcast it;
    * `:run` — the command is authorised: carry it out (its result is the reply).

  Actions come in the order they must be carried out (stop before grant).

  ## Replies

  `:ok`, `{:ok, :granted}` (request or take on a free helm), `{:ok, :in_control}` (the
  sender already pilots), `{:ok, :pending}` (request waits for the pilot),
  `{:ok, :takeover}` (countdown running), or `{:error, reason}` with reason
  `"not_in_control"`, `"busy"`, `"forbidden"`, `"no_request"`, `"stale_command"` or a
  description of a malformed stamp. A refused event changes nothing (except that a message
  from the pilot always counts for the deadman).
  """

  @type role :: :pilot | :observer | :main_station
  @type party :: %{
          required(:id) => String.t(),
          required(:role) => role(),
          optional(atom()) => term()
        }

  @type helm ::
          :free
          | {:piloted, party()}
          | {:requested, party(), party()}
          | {:takeover, party(), party()}

  @type stamp :: :none | {:epoch, term()}

  @type event ::
          {:request, party()}
          | {:answer, party(), boolean()}
          | {:take, party()}
          | {:release, party()}
          | {:heartbeat, party()}
          | {:command, party(), stamp()}
          | {:leave, String.t(), String.t()}
          | :request_timeout
          | :takeover_due
          | {:tick, pos_integer()}

  @type action ::
          {:stop, String.t()}
          | {:grant, party()}
          | {:revoke, party(), String.t()}
          | {:push, party(), String.t(), map()}
          | :changed
          | :run

  @type reply ::
          :ok | {:ok, :granted | :in_control | :pending | :takeover} | {:error, String.t()}

  @typedoc """
  * `helm` — the state above
  * `epoch` — incremented on every grant and deadman trip; commands must carry the current one
  * `last_seen_ms` — `now` of the pilot's last message (or of the grant)
  * `tripped` — the deadman has fired and the pilot has been silent since
  """
  @type t :: %__MODULE__{
          helm: helm(),
          epoch: non_neg_integer(),
          last_seen_ms: integer() | nil,
          tripped: boolean()
        }
  defstruct helm: :free, epoch: 0, last_seen_ms: nil, tripped: false

  @doc """
  A free helm whose epoch starts at `epoch` (default 0; the first grant gives `epoch + 1`).
  `Neptunus.Vehicle.Helm` starts each helm at a value no earlier helm of the node reached,
  so an epoch never repeats within a node's life (see its moduledoc).
  """
  @spec new(non_neg_integer()) :: t()
  def new(epoch \\ 0) when is_integer(epoch) and epoch >= 0, do: %__MODULE__{epoch: epoch}

  @doc "The pilot, or nil."
  @spec pilot(t()) :: party() | nil
  def pilot(%__MODULE__{helm: :free}), do: nil
  def pilot(%__MODULE__{helm: {:piloted, p}}), do: p
  def pilot(%__MODULE__{helm: {_, p, _}}), do: p

  @doc "Everyone the helm state refers to (pilot, requester, main station taking over)."
  @spec parties(t()) :: [party()]
  def parties(%__MODULE__{helm: :free}), do: []
  def parties(%__MODULE__{helm: {:piloted, p}}), do: [p]
  def parties(%__MODULE__{helm: {_, p, q}}), do: [p, q]

  @doc "The state's name: `:free`, `:piloted`, `:requested` or `:takeover`."
  @spec name(t()) :: :free | :piloted | :requested | :takeover
  def name(%__MODULE__{helm: :free}), do: :free
  def name(%__MODULE__{helm: helm}), do: elem(helm, 0)

  @doc "Applies `event` at time `now` (ms). See the moduledoc for replies and actions."
  @spec handle(t(), event(), integer()) :: {reply(), t(), [action()]}
  def handle(%__MODULE__{} = s, event, now) do
    s = if from_pilot?(s, event), do: %{s | last_seen_ms: now}, else: s
    {reply, s, actions} = step(s, event, now)
    # only a command that runs re-arms a tripped deadman: a pilot whose page only heartbeats
    # (a throttled background tab) is not stopped again and again
    s = if :run in actions, do: %{s | tripped: false}, else: s
    {reply, s, actions}
  end

  # Events that carry a party: request, answer, take, release, heartbeat, command.
  defp from_pilot?(s, event) when is_tuple(event) and is_map(elem(event, 1)),
    do: pilot_id(s.helm) == elem(event, 1).id

  defp from_pilot?(_s, _event), do: false

  # -- request_control -----------------------------------------------------------------------

  defp step(s, {:request, %{role: :observer}}, _now), do: {{:error, "forbidden"}, s, []}

  defp step(%{helm: :free} = s, {:request, p}, now), do: grant(s, p, now, [])

  defp step(s, {:request, p}, _now) do
    case s.helm do
      {:piloted, %{id: id}} when id == p.id ->
        {{:ok, :in_control}, s, []}

      {:piloted, pilot} ->
        push = {:push, pilot, "control_request", %{from: p}}
        {{:ok, :pending}, %{s | helm: {:requested, pilot, p}}, [push, :changed]}

      {_, %{id: id}, _} when id == p.id ->
        {{:ok, :in_control}, s, []}

      {:requested, _, %{id: id}} when id == p.id ->
        {{:ok, :pending}, s, []}

      {:takeover, _, %{id: id}} when id == p.id ->
        {{:ok, :takeover}, s, []}

      _ ->
        {{:error, "busy"}, s, []}
    end
  end

  # -- answer_request ------------------------------------------------------------------------

  defp step(s, {:answer, p, accept}, now) do
    case s.helm do
      {:requested, %{id: id} = pilot, requester} when id == p.id ->
        if accept do
          transfer(s, pilot, requester, "control_transferred", now)
        else
          denied = {:push, requester, "request_denied", %{reason: "denied"}}
          {:ok, %{s | helm: {:piloted, pilot}}, [denied, :changed]}
        end

      helm ->
        if pilot_id(helm) == p.id,
          do: {{:error, "no_request"}, s, []},
          else: {{:error, "not_in_control"}, s, []}
    end
  end

  # -- take_control (main station) -----------------------------------------------------------

  defp step(s, {:take, %{role: role}}, _now) when role != :main_station,
    do: {{:error, "forbidden"}, s, []}

  defp step(%{helm: :free} = s, {:take, m}, now), do: grant(s, m, now, [])

  defp step(s, {:take, m}, _now) do
    case s.helm do
      {:piloted, %{id: id}} when id == m.id ->
        {{:ok, :in_control}, s, []}

      {:piloted, pilot} ->
        {{:ok, :takeover}, %{s | helm: {:takeover, pilot, m}}, [:changed]}

      {_, %{id: id}, _} when id == m.id ->
        {{:ok, :in_control}, s, []}

      {:requested, pilot, %{id: id}} when id == m.id ->
        {{:ok, :takeover}, %{s | helm: {:takeover, pilot, m}}, [:changed]}

      {:requested, pilot, requester} ->
        denied = {:push, requester, "request_denied", %{reason: "main_station_takeover"}}
        {{:ok, :takeover}, %{s | helm: {:takeover, pilot, m}}, [denied, :changed]}

      {:takeover, _, %{id: id}} when id == m.id ->
        {{:ok, :takeover}, s, []}

      {:takeover, _, _} ->
        {{:error, "busy"}, s, []}
    end
  end

  # -- release_control -----------------------------------------------------------------------

  defp step(s, {:release, p}, now) do
    case s.helm do
      {:piloted, %{id: id} = pilot} when id == p.id ->
        free(s, pilot, "released")

      # the pilot lets go while someone waits for the helm: it goes to them at once
      {_, %{id: id} = pilot, next} when id == p.id ->
        transfer(s, pilot, next, "released", now)

      # a requester withdraws its request, the main station cancels its takeover
      {_, pilot, %{id: id}} when id == p.id ->
        {:ok, %{s | helm: {:piloted, pilot}}, [:changed]}

      _ ->
        {{:error, "not_in_control"}, s, []}
    end
  end

  # -- the pilot's heartbeat and commands ----------------------------------------------------

  defp step(s, {:heartbeat, p}, _now) do
    if pilot_id(s.helm) == p.id, do: {:ok, s, []}, else: {{:error, "not_in_control"}, s, []}
  end

  defp step(s, {:command, p, stamp}, _now) do
    cond do
      pilot_id(s.helm) != p.id -> {{:error, "not_in_control"}, s, []}
      stamp == :none -> {:ok, s, [:run]}
      stamp == {:epoch, s.epoch} -> {:ok, s, [:run]}
      match?({:epoch, e} when is_integer(e), stamp) -> {{:error, "stale_command"}, s, []}
      stamp == {:epoch, nil} -> {{:error, "missing field: epoch"}, s, []}
      true -> {{:error, "epoch must be an integer (from the grant)"}, s, []}
    end
  end

  # -- a party's connection closes or leaves the vehicle's topic -----------------------------

  defp step(s, {:leave, id, reason}, now) do
    case s.helm do
      {:piloted, %{id: ^id} = pilot} -> free(s, pilot, reason)
      {_, %{id: ^id} = pilot, next} -> transfer(s, pilot, next, reason, now)
      {_, pilot, %{id: ^id}} -> {:ok, %{s | helm: {:piloted, pilot}}, [:changed]}
      _ -> {:ok, s, []}
    end
  end

  # -- timers --------------------------------------------------------------------------------

  defp step(%{helm: {:requested, pilot, requester}} = s, :request_timeout, _now) do
    denied = {:push, requester, "request_denied", %{reason: "request_timeout"}}
    {:ok, %{s | helm: {:piloted, pilot}}, [denied, :changed]}
  end

  defp step(%{helm: {:takeover, pilot, main}} = s, :takeover_due, now),
    do: transfer(s, pilot, main, "main_station_takeover", now)

  # a timer of a state that has been left meanwhile
  defp step(s, event, _now) when event in [:request_timeout, :takeover_due], do: {:ok, s, []}

  defp step(%{helm: :free} = s, {:tick, _deadman_ms}, _now), do: {:ok, s, []}

  defp step(s, {:tick, deadman_ms}, now) do
    if not s.tripped and now - s.last_seen_ms > deadman_ms do
      {:ok, %{s | tripped: true, epoch: s.epoch + 1}, [{:stop, "deadman"}, :changed]}
    else
      {:ok, s, []}
    end
  end

  # -- transitions ---------------------------------------------------------------------------

  defp grant(s, p, now, before) do
    s = %{s | helm: {:piloted, p}, epoch: s.epoch + 1, last_seen_ms: now, tripped: false}
    {{:ok, :granted}, s, before ++ [{:grant, p}, :changed]}
  end

  defp transfer(s, from, to, reason, now) do
    {_, s, actions} = grant(s, to, now, [{:stop, reason}, {:revoke, from, reason}])
    {:ok, s, actions}
  end

  defp free(s, pilot, reason) do
    s = %{s | helm: :free, last_seen_ms: nil, tripped: false}
    {:ok, s, [{:stop, reason}, {:revoke, pilot, reason}, :changed]}
  end

  defp pilot_id(:free), do: nil
  defp pilot_id({:piloted, %{id: id}}), do: id
  defp pilot_id({_, %{id: id}, _}), do: id
end
