defmodule Neptunus.Vehicle.Helm do
  @moduledoc """
  Who is in control of a vehicle: one pilot, any number of observers, control handed over by
  request and acknowledge, the main station's takeover with a warning, the deadman, and the
  safety stops that go with them.

  A `:gen_statem` that runs `Neptunus.Helm.Policy` (every decision is there, with the states,
  events, stamps and reasons documented) and carries out its actions: it calls
  `Neptunus.Vehicle.Control` (stop, thrust — so a command and a transfer can never overtake
  each other), broadcasts `helm` on `"vehicle:<id>"`, sends targeted events to parties,
  monitors the pilot, the requester and the main station taking over (a connection that dies
  is a `{:leave, id, "pilot_disconnected"}`; one on another node that is cut off, a
  `:noconnection`, is `"pilot_unreachable"`), and keeps two timers:

    * `:state_timeout` — the pending request (`request_timeout_ms`, default 10 s) and the
      takeover countdown (`takeover_ms`, default 3 s); leaving the state cancels it;
    * a deadman check every `tick_ms` (default `deadman_ms / 5`), which compares the pilot's
      last message with the injected `clock` (default `Neptunus.Clock.monotonic_ms/0`).
      Tests inject a clock they move by hand and call `check_deadman/1`.

  It starts after Control in the vehicle's `:rest_for_one` tree and drives the thrusters
  neutral when it starts (stop reason `helm_started`): a helm that crashed forgets its pilot,
  and the vehicle must not keep the lost pilot's last command.

  ## Epochs

  A command stamp (`epoch`, see `Neptunus.Helm.Policy`) must never repeat within the node's
  life, or a `thrust` stamped before a helm crash (or a restart of the vehicle's tree) would
  be taken as current by the helm that replaced it. So a helm does not start at 0: it
  starts at `first_epoch/0`, the microseconds since the VM started (monotonic), and counts up
  by one per grant or deadman trip from there. A helm that lived `Δ` µs issued fewer than
  `Δ` epochs (each is one handled event — a grant calls Control and notifies parties, a
  deadman trip happens at most once per tick — and takes far longer than a microsecond), so
  the next helm, starting `Δ` µs later, starts above every epoch its predecessors issued.
  Epochs stay below 2⁵³ (JSON- and JavaScript-safe) for 285 years of uptime.

  ## Parties

  The caller of every function is a `t:party/0`: `%{id, name, role, pid, notify}` — one
  connection of one user. `id` tells parties apart; `pid` is monitored while the party
  matters; `notify.(event, payload)` delivers a targeted event to that connection
  (`control_request`, `control_granted`, `control_lost`, `request_denied`).

  ## Priority

  The vehicle's control path runs at process priority `:high`: this process,
  `Neptunus.Vehicle.Control` and the board link `Neptunus.Vehicle.Board.OpenROV.UART`. Each
  broadcast of telemetry makes every observer's connection process runnable at once (1 000 of them
  for a few milliseconds of both cores); a command must not wait behind them. Their work is
  bounded — commands come only through the pilot's connection (which runs at `:high` too,
  within a frame budget, see `NeptunusWeb.Socket` and `NeptunusWeb.Socket.FlowControl`), the rest
  on fixed-rate timers and the board's serial line — so they cannot starve `:normal` and
  `:low` processes. Other connections run at `:low`, which still runs whenever nothing more
  urgent is runnable.

  ## Options

  `:id` (required) and `:helm`, a keyword list overriding `defaults/0`: `deadman_ms` (500),
  `request_timeout_ms` (10 000), `takeover_ms` (3 000), `heartbeat_ms` (100, what clients
  are told to send), `tick_ms`, `clock`. The node's vehicles get the application's `:helm`
  config (`Neptunus.Config.Helm`) here, from `Neptunus.Application`.
  """
  @behaviour :gen_statem

  require Logger

  alias Neptunus.Helm.Policy
  alias Neptunus.PubSub
  alias Neptunus.Vehicle.{Control, Telemetry}

  @defaults [deadman_ms: 500, request_timeout_ms: 10_000, takeover_ms: 3_000, heartbeat_ms: 100]

  @doc "The helm's timing when `:helm` does not say (the one place of these defaults)."
  @spec defaults() :: keyword(pos_integer())
  def defaults, do: @defaults

  @type party :: %{
          required(:id) => String.t(),
          required(:name) => String.t(),
          required(:role) => Policy.role(),
          required(:pid) => pid(),
          required(:notify) => (String.t(), map() -> any())
        }
  @type reply :: {:ok, map()} | {:error, String.t()}

  @restarting "vehicle restarting: try again"
  @unreachable "vehicle_unreachable"

  defmodule Data do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            topic: String.t(),
            policy: Neptunus.Helm.Policy.t(),
            monitors: %{optional(pid()) => {reference(), String.t()}},
            clock: (() -> integer()),
            deadman_ms: pos_integer(),
            request_timeout_ms: pos_integer(),
            takeover_ms: non_neg_integer(),
            heartbeat_ms: pos_integer(),
            tick_ms: pos_integer(),
            since_wall_ms: integer() | nil,
            deadline_ms: integer() | nil
          }
    @enforce_keys [:id, :topic, :policy, :clock, :deadman_ms, :request_timeout_ms] ++
                    [:takeover_ms, :heartbeat_ms, :tick_ms]
    defstruct @enforce_keys ++ [monitors: %{}, since_wall_ms: nil, deadline_ms: nil]
  end

  @spec child_spec(keyword()) :: Supervisor.child_spec()
  def child_spec(opts) do
    %{id: __MODULE__, start: {__MODULE__, :start_link, [opts]}}
  end

  @spec start_link(keyword()) :: :gen_statem.start_ret()
  def start_link(opts) do
    :gen_statem.start_link(via(Keyword.fetch!(opts, :id)), __MODULE__, opts, [])
  end

  @doc """
  Asks for control. A free helm is granted at once: `{:ok, %{status: "granted", grant: g}}`
  (`g` as in `control_granted`). Otherwise the pilot gets `control_request` and the reply is
  `{:ok, %{status: "pending", timeout_ms: t}}`; the answer comes as `control_granted` or
  `request_denied`. Errors: `busy`, `forbidden` (observers).
  """
  @spec request_control(String.t(), party()) :: reply()
  def request_control(id, party), do: call(id, {:helm, {:request, party}})

  @doc "The pilot answers the pending request. Errors: `no_request`, `not_in_control`."
  @spec answer_request(String.t(), party(), boolean()) :: reply()
  def answer_request(id, party, accept) when is_boolean(accept),
    do: call(id, {:helm, {:answer, party, accept}})

  @doc """
  The main station takes control without acknowledge: `{:ok, %{status: "takeover",
  countdown_ms: ms}}` and the transfer after the countdown (`{:ok, %{status: "granted",
  ...}}` on a free helm). Errors: `forbidden` (not the main station), `busy`.
  """
  @spec take_control(String.t(), party()) :: reply()
  def take_control(id, party), do: call(id, {:helm, {:take, party}})

  @doc """
  Gives the helm up (stop, reason `released`; to whoever is waiting for it, if anyone), or
  withdraws a request / cancels a takeover. Error: `not_in_control`.
  """
  @spec release_control(String.t(), party()) :: reply()
  def release_control(id, party), do: call(id, {:helm, {:release, party}})

  @doc "The pilot's heartbeat (feeds the deadman): `{:ok, %{}}`. Error: `not_in_control`."
  @spec heartbeat(String.t(), party()) :: reply()
  def heartbeat(id, party) do
    # 10 per second: the reply stays empty
    with {:ok, _} <- call(id, {:helm, {:heartbeat, party}}), do: {:ok, %{}}
  end

  @doc """
  Thrust from the pilot: `payload` as `Control.thrust/2` takes it plus the stamp `"epoch"`
  (from the grant). Errors: `not_in_control`, `stale_command`, `missing field: epoch`, or
  Control's reasons.
  """
  @spec thrust(String.t(), party(), map()) :: reply()
  def thrust(id, party, payload) when is_map(payload) do
    {epoch, params} = Map.pop(payload, "epoch")
    command(id, party, {:epoch, epoch}, fn -> Control.thrust(id, params) end)
  end

  @doc "Stop from the pilot (any time, no stamp needed). Error: `not_in_control`."
  @spec stop(String.t(), party(), String.t()) :: reply()
  def stop(id, party, reason),
    do: command(id, party, :none, fn -> Control.stop(id, reason) end)

  @doc """
  Runs `fun` (in the helm's process, so no transfer can come between the check and the
  command) if `party` is the pilot and `stamp` is `:none` or `{:epoch, current}`; replies
  with `fun`'s result, which must be `{:ok, map}` or `{:error, reason}`. For pilot-only
  commands other than thrust and stop (simulator controls, lights, …).
  """
  @spec command(String.t(), party(), Policy.stamp(), (() -> reply())) :: reply()
  def command(id, party, stamp, fun) when is_function(fun, 0),
    do: call(id, {:command, party, stamp, fun})

  @doc """
  Sends the vehicle a request whose outcome comes later, if `party` is the pilot (as
  `command/4` checks): calls `request.(id, notify)` in the helm's process — a board command
  (`Neptunus.Vehicle.Board.command/3`) or a position source's (`notify` gets `:ok` or
  `{:error, reason}` when the vehicle answers). Replies `{:ok, %{}}` once asked, or why not.
  """
  @spec board_request(
          String.t(),
          party(),
          (String.t(), notify -> :ok | {:error, String.t()}),
          notify
        ) :: reply()
        when notify: (:ok | {:error, String.t()} -> term())
  def board_request(id, party, request, notify) do
    command(id, party, :none, fn ->
      case request.(id, notify) do
        :ok -> {:ok, %{}}
        {:error, reason} -> {:error, reason}
      end
    end)
  end

  @doc """
  A party's connection left the vehicle's topic or closed (`reason`: `pilot_left`,
  `pilot_disconnected`). Its pilot's helm is freed and the vehicle stops. A vehicle that is
  unreachable is left already (its helm monitors every party's connection).
  """
  @spec leave(String.t(), String.t(), String.t()) :: :ok
  def leave(id, party_id, reason) do
    # a helm that is restarting has forgotten every party already
    case call(id, {:helm, {:leave, party_id, reason}}) do
      {:ok, _} -> :ok
      {:error, @restarting} -> :ok
      # a cut-off vehicle's helm learns it from its monitor (`pilot_unreachable`)
      {:error, @unreachable} -> :ok
    end
  end

  @doc "The helm as broadcast in `helm` (see docs/API.md)."
  @spec status(String.t()) :: map()
  def status(id), do: call(id, :status)

  @doc "Runs the deadman check now (tests move an injected clock, then call this)."
  @spec check_deadman(String.t()) :: :ok
  def check_deadman(id), do: call(id, :check_deadman)

  defp call(id, :status), do: :gen_statem.call(target(id), :status)
  defp call(id, :check_deadman), do: :gen_statem.call(target(id), :check_deadman)

  # A request while the helm is down (its vehicle's control chain restarting after a crash)
  # is refused with a reason instead of crashing the caller (a client's channel): the new
  # helm drives neutral and says `stopped` as it starts, and the client may ask again. A
  # vehicle that no longer runs is no restart: the caller exits as before. A vehicle on a
  # node that is cut off (or went down during the call) is `vehicle_unreachable`.
  defp call(id, request) do
    case target(id) do
      :unreachable -> {:error, @unreachable}
      target -> :gen_statem.call(target, request)
    end
  catch
    :exit, {reason, {:gen_statem, :call, _}} = exit ->
      cond do
        unreachable?(reason) -> {:error, @unreachable}
        helm_down?(reason) and Neptunus.Fleet.exists?(id) -> {:error, @restarting}
        true -> :erlang.raise(:exit, exit, __STACKTRACE__)
      end
  end

  defp helm_down?(reason) when reason in [:noproc, :normal, :killed, :shutdown], do: true
  defp helm_down?({:shutdown, _}), do: true
  defp helm_down?(_), do: false

  defp unreachable?(:noconnection), do: true
  defp unreachable?({:nodedown, _}), do: true
  defp unreachable?(_), do: false

  # This node's helm by its name; another node's by the pid the fleet's directory knows
  # (`Neptunus.Fleet.locate/1`): the helm lives only on its vehicle's node.
  defp target(id) do
    if Neptunus.Fleet.local?(id) do
      via(id)
    else
      case Neptunus.Fleet.locate(id) do
        {:ok, _node, pid} -> pid
        {:error, :unreachable} -> :unreachable
        {:error, :not_found} -> via(id)
      end
    end
  end

  defp via(id), do: Neptunus.Fleet.via(__MODULE__, id)

  # Callbacks

  @impl true
  def callback_mode, do: :handle_event_function

  @impl true
  def init(opts) do
    # The control path — this process, Control and the board link — runs at :high, so a
    # pilot's command is not queued behind the telemetry fan-out (see the moduledoc).
    Process.flag(:priority, :high)
    id = Keyword.fetch!(opts, :id)
    # in the cluster's directory while it lives (browsers on other nodes find it there)
    :ok = Neptunus.Fleet.publish(id)

    config = Keyword.merge(@defaults, Keyword.get(opts, :helm, []))

    deadman_ms = Keyword.fetch!(config, :deadman_ms)

    data = %Data{
      id: id,
      topic: Telemetry.topic(id),
      policy: Policy.new(first_epoch()),
      clock: Keyword.get(config, :clock, &Neptunus.Clock.monotonic_ms/0),
      deadman_ms: deadman_ms,
      request_timeout_ms: Keyword.fetch!(config, :request_timeout_ms),
      takeover_ms: Keyword.fetch!(config, :takeover_ms),
      heartbeat_ms: Keyword.fetch!(config, :heartbeat_ms),
      tick_ms: Keyword.get(config, :tick_ms, max(div(deadman_ms, 5), 10))
    }

    {:ok, :free, data, [{:next_event, :internal, :start}]}
  end

  @impl true
  def handle_event(:internal, :start, _state, data) do
    {:ok, _} = Control.stop(data.id, "helm_started")
    broadcast(data)
    {:keep_state_and_data, [deadman_timer(data)]}
  end

  def handle_event({:call, from}, {:helm, event}, state, data) do
    {reply, data, _run?} = step(data, event)
    transition(state, data, [{:reply, from, public_reply(reply, data)}])
  end

  def handle_event({:call, from}, {:command, party, stamp, fun}, state, data) do
    {reply, data, run?} = step(data, {:command, party, stamp})
    reply = if run?, do: run(fun), else: reply
    transition(state, data, [{:reply, from, reply}])
  end

  def handle_event({:call, from}, :status, _state, data),
    do: {:keep_state_and_data, [{:reply, from, public(data)}]}

  def handle_event({:call, from}, :check_deadman, state, data) do
    {:ok, data, false} = step(data, {:tick, data.deadman_ms})
    transition(state, data, [{:reply, from, :ok}])
  end

  def handle_event({:timeout, :deadman}, :check, state, data) do
    {:ok, data, false} = step(data, {:tick, data.deadman_ms})
    transition(state, data, [deadman_timer(data)])
  end

  def handle_event(:state_timeout, event, state, data)
      when event in [:request_timeout, :takeover_due] do
    {:ok, data, false} = step(data, event)
    transition(state, data, [])
  end

  def handle_event(:info, {:DOWN, ref, :process, pid, reason}, state, data) do
    case Map.pop(data.monitors, pid) do
      {{^ref, party_id}, monitors} ->
        {:ok, data, false} =
          step(%{data | monitors: monitors}, {:leave, party_id, leave_reason(reason)})

        transition(state, data, [])

      _ ->
        :keep_state_and_data
    end
  end

  def handle_event(:info, msg, _state, _data) do
    Logger.debug("helm ignored #{inspect(msg)}")
    :keep_state_and_data
  end

  # A party's connection on another node that is cut off (`:noconnection`) is unreachable;
  # any other end of it is a disconnection.
  defp leave_reason(:noconnection), do: "pilot_unreachable"
  defp leave_reason(_reason), do: "pilot_disconnected"

  # Runs the policy and carries out its actions; `run?` tells whether a command may run.
  defp step(data, event) do
    {reply, policy, actions} = Policy.handle(data.policy, event, data.clock.())
    data = %{data | policy: policy}
    data = Enum.reduce(actions, data, &act/2)
    {reply, sync_monitors(data), :run in actions}
  end

  defp act({:stop, reason}, data) do
    {:ok, _} = Control.stop(data.id, reason)
    data
  end

  defp act({:grant, party}, data) do
    data = %{data | since_wall_ms: Neptunus.Clock.wall_ms()}
    notify(party, "control_granted", grant(data))
    data
  end

  defp act({:revoke, party, reason}, data) do
    notify(party, "control_lost", %{reason: reason})
    data
  end

  defp act({:push, party, event, payload}, data) do
    notify(party, event, Map.new(payload, fn {k, v} -> {k, public_party(v)} end))
    data
  end

  defp act(:changed, data) do
    # countdowns of a state just entered are measured from now (the state_timeout starts now)
    data =
      case Policy.name(data.policy) do
        :requested -> %{data | deadline_ms: now_ms() + data.request_timeout_ms}
        :takeover -> %{data | deadline_ms: now_ms() + data.takeover_ms}
        _ -> %{data | deadline_ms: nil}
      end

    broadcast(data)
    data
  end

  defp act(:run, data), do: data

  # The gen_statem state is the helm with parties reduced to their ids, so a state timeout
  # runs from entering a state until leaving it.
  defp transition(state, data, actions) do
    case state_key(data.policy) do
      ^state ->
        {:keep_state, data, actions}

      {:requested, _, _} = next ->
        {:next_state, next, data,
         [{:state_timeout, data.request_timeout_ms, :request_timeout} | actions]}

      {:takeover, _, _} = next ->
        {:next_state, next, data, [{:state_timeout, data.takeover_ms, :takeover_due} | actions]}

      next ->
        {:next_state, next, data, actions}
    end
  end

  defp state_key(policy) do
    case policy.helm do
      :free -> :free
      {:piloted, p} -> {:piloted, p.id}
      {name, p, q} -> {name, p.id, q.id}
    end
  end

  defp sync_monitors(data) do
    wanted = Map.new(Policy.parties(data.policy), &{&1.pid, &1.id})

    kept =
      Enum.reduce(data.monitors, %{}, fn {pid, {ref, _} = entry}, acc ->
        if Map.has_key?(wanted, pid),
          do: Map.put(acc, pid, entry),
          else: Process.demonitor(ref, [:flush]) && acc
      end)

    monitors =
      Enum.reduce(wanted, kept, fn {pid, party_id}, acc ->
        Map.put_new_lazy(acc, pid, fn -> {Process.monitor(pid), party_id} end)
      end)

    %{data | monitors: monitors}
  end

  defp run(fun) do
    case fun.() do
      {:ok, response} when is_map(response) ->
        {:ok, response}

      {:error, reason} when is_binary(reason) ->
        {:error, reason}

      other ->
        raise "a helm command must return {:ok, map} or {:error, reason}, got #{inspect(other)}"
    end
  end

  defp notify(%{notify: notify} = party, event, payload) when is_function(notify, 2) do
    notify.(event, payload)
  rescue
    exception ->
      Logger.warning(
        "helm could not notify #{Neptunus.Log.safe(party.name)}: " <>
          Neptunus.Log.safe(Exception.message(exception))
      )
  end

  defp deadman_timer(data), do: {{:timeout, :deadman}, data.tick_ms, :check}

  defp broadcast(data), do: PubSub.broadcast(data.topic, "helm", public(data))

  # -- payloads (docs/API.md) ------------------------------------------------------------------

  defp public_reply(:ok, data), do: {:ok, %{helm: public(data)}}

  defp public_reply({:ok, status}, data) when status in [:granted, :in_control],
    do: {:ok, %{status: "granted", grant: grant(data)}}

  defp public_reply({:ok, :pending}, data),
    do: {:ok, %{status: "pending", timeout_ms: remaining(data)}}

  defp public_reply({:ok, :takeover}, data),
    do: {:ok, %{status: "takeover", countdown_ms: remaining(data)}}

  defp public_reply({:error, reason}, _data), do: {:error, reason}

  defp grant(data) do
    %{
      epoch: data.policy.epoch,
      pilot: data.policy |> Policy.pilot() |> public_party(data),
      control: Control.status(data.id),
      deadman_ms: data.deadman_ms,
      heartbeat_ms: data.heartbeat_ms
    }
  end

  defp public(data) do
    policy = data.policy
    base = %{state: Atom.to_string(Policy.name(policy)), epoch: policy.epoch}

    parts =
      case policy.helm do
        :free ->
          %{pilot: nil, request: nil, takeover: nil}

        {:piloted, p} ->
          %{pilot: public_party(p, data), request: nil, takeover: nil}

        {:requested, p, r} ->
          %{
            pilot: public_party(p, data),
            request: %{from: public_party(r), remaining_ms: remaining(data)},
            takeover: nil
          }

        {:takeover, p, m} ->
          %{
            pilot: public_party(p, data),
            request: nil,
            takeover: %{by: public_party(m), countdown_ms: remaining(data)}
          }
      end

    base
    |> Map.merge(parts)
    |> Map.merge(%{
      deadman_ms: data.deadman_ms,
      heartbeat_ms: data.heartbeat_ms,
      request_timeout_ms: data.request_timeout_ms,
      takeover_ms: data.takeover_ms
    })
  end

  defp public_party(%{id: id, name: name, role: role}),
    do: %{id: id, name: name, role: Atom.to_string(role)}

  defp public_party(other), do: other

  defp public_party(party, data), do: Map.put(public_party(party), :since, data.since_wall_ms)

  defp remaining(%Data{deadline_ms: nil}), do: 0
  defp remaining(data), do: max(data.deadline_ms - now_ms(), 0)

  defp now_ms, do: Neptunus.Clock.monotonic_ms()

  @doc """
  Where a helm starting now starts its epochs: the microseconds since the node (the VM)
  started. See "Epochs" in the moduledoc.
  """
  @spec first_epoch() :: non_neg_integer()
  def first_epoch do
    Neptunus.Clock.uptime_us()
  end
end
