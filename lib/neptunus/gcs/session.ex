defmodule Neptunus.GCS.Session do
  @moduledoc """
  One ground station's session, decided (pure): `handle(session, event) -> {session,
  actions}`. What each message from the ground station means, which replies go back and
  what the vehicle is asked to do — always through the helm, as for a browser.
  `Neptunus.GCS.Link` runs it and carries out the actions.

  A session is one ground station on one endpoint: a source address on `udpin`, a
  connection on `tcpin`, the configured peer of a `udpout`. It sees every vehicle of the
  node, each a MAVLink system (`vehicles`: `%{sysid => %{id, board}}`); messages for other
  systems are not ours and are ignored. It belongs to the first ground station system id
  it hears (a router may put several behind one address: the others are ignored and
  counted, `:foreign`).

  ## Who it is (`identity`)

  `%{name, role, trusted}`, decided by its first admitted message (`Neptunus.GCS.Admission`):
  a signed one names its key's ground station and role; an unsigned one on loopback is a
  pilot in local mode (anyone on this computer may pilot, as in a browser) and an observer
  in secure mode. `trusted` (local mode, loopback, a system id of
  `NEPTUNUS_MAVLINK_TRUSTED`): it may take a free helm without asking, by its first
  MANUAL_CONTROL or arm.

  ## Events

    * `{:message, message, now_ms}` — an admitted message from the ground station;
    * `{:vehicle, sysid, view}` — the vehicle's latest state from its source (`helm`,
      `control`, `board`, and `messages`: the streamed messages it can say now — no
      LOCAL_POSITION_NED without a valid position), every tick;
    * `{:helm, sysid, event, payload}` — the helm's targeted events for this party
      (`control_granted`, `control_lost`, `control_request`, `request_denied`);
    * `{:result, ref, result}` — what an intent gave (`{:ok, map}` / `{:error, reason}`);
    * `{:check, now_ms}` — periodic: a session silent for `timeout_ms` ends.

  ## Actions

    * `{:send, sysid, name, fields}` — a message from vehicle `sysid` to the ground station;
    * `{:text, sysid, severity, text}` — a STATUSTEXT from vehicle `sysid` (chunked by the
      shell, which numbers the chunks);
    * `{:frames, sysid, names}` — the vehicle's latest shared frames of these messages;
    * `{:intent, ref, sysid, intent}` — ask the vehicle (helm, control, board); its result
      comes back as `{:result, ref, result}` (see `t:intent/0`);
    * `:close` — the session ends (its party leaves every helm).

  ## The helm

  MANUAL_CONTROL (and RC_CHANNELS_OVERRIDE) move a vehicle only while this session holds
  its helm: the demand (`Neptunus.GCS.Manual`) goes to `Neptunus.Vehicle.Helm.thrust/3`
  stamped with the helm's epoch when it changes, a repeated one is only the pilot's
  heartbeat (so after any stop only fresh input moves the vehicle, as on the operator page).
  From anyone else they are ignored and counted (`:manual_ignored`). The ground station's
  own HEARTBEAT and MANUAL_CONTROL feed the helm's deadman: silence stops the vehicle within
  `deadman_ms`, as for a browser pilot.

  `MAV_CMD_REQUEST_OPERATOR_CONTROL` (32100) asks for the helm (param 2 = 1), exactly as a
  browser's `request_control`: granted at once on a free helm (ACCEPTED), else the pilot is
  asked — a browser sees the request, a pilot ground station gets the command with the
  requester's system id — and the ACK says IN_PROGRESS, followed by ACCEPTED when the helm
  comes, DENIED when the pilot refuses or the request times out. A main station's request
  is its takeover (the countdown, then the helm). The pilot ground station answers a
  request by sending the command again: allow takeover (param 3 = 1) gives the helm to the
  requester, 0 refuses; action 0 releases the helm (to the requester, if one waits).
  CONTROL_STATUS (from the vehicle's source) tells every ground station who flies.
  """

  alias Neptunus.GCS.{Manual, Modes, Params, Party, Scheduler}

  # MAV_RESULT
  @accepted 0
  @temporarily_rejected 1
  @denied 2
  @unsupported 3
  @failed 4
  @in_progress 5

  # MAV_SEVERITY
  @warning 4
  @notice 5
  @info 6

  # MAV_CMD
  @arm_disarm 400
  @do_set_mode 176
  @do_set_servo 183
  @do_mount_control 205
  @do_gimbal_pitchyaw 1000
  @get_message_interval 510
  @set_message_interval 511
  @request_message 512
  @request_capabilities 520
  @request_operator_control 32_100

  @lights_servo 9
  @tilt_servo 8
  @max_pending 8
  @default_timeout_ms 5_000

  @not_in_control "not in control (ask: MAV_CMD_REQUEST_OPERATOR_CONTROL)"

  @type identity :: %{
          name: String.t(),
          role: :pilot | :observer | :main_station,
          trusted: boolean()
        }

  @type intent ::
          {:thrust, Manual.axes(), integer()}
          | :heartbeat
          | :request_control
          | :take_control
          | :release_control
          | {:answer, boolean()}
          | {:commands, [{String.t(), map()}]}
          | {:arm, boolean()}
          | {:param_set, String.t(), Params.set()}
          | :params
          | :status

  @type action ::
          {:send, 1..255, atom(), map()}
          | {:text, 1..255, 0..7, String.t()}
          | {:frames, 1..255, [atom()]}
          | {:intent, pos_integer(), 1..255, intent()}
          | :close

  @typedoc "What the session knows of one vehicle."
  @type vehicle :: %{
          id: String.t(),
          board: atom(),
          arms: boolean(),
          view: map() | nil,
          pilot: boolean(),
          epoch: integer() | nil,
          last_axes: Manual.axes() | nil,
          asked: boolean(),
          awaiting_helm: boolean()
        }

  defstruct [
    :id,
    :identity,
    gcs: nil,
    vehicles: %{},
    scheduler: %Scheduler{},
    pending: %{},
    next_ref: 1,
    last_heard_ms: nil,
    timeout_ms: @default_timeout_ms,
    counters: %{}
  ]

  @typedoc """
  * `id` — the session (endpoint and peer), part of its helm party's id
  * `identity` — who it is (see the moduledoc)
  * `gcs` — `{system, component}` of the ground station, from its first message
  * `vehicles` — `%{sysid => vehicle}`
  * `scheduler` — its message intervals (`Neptunus.GCS.Scheduler`)
  * `pending` — intents waiting for their result: `ref => context`
  * `counters` — messages handled, ignored and refused, by kind
  """
  @type t :: %__MODULE__{
          id: String.t(),
          identity: identity(),
          gcs: {byte(), byte()} | nil,
          vehicles: %{(1..255) => vehicle()},
          scheduler: Scheduler.t(),
          pending: %{pos_integer() => term()},
          next_ref: pos_integer(),
          last_heard_ms: integer() | nil,
          timeout_ms: pos_integer(),
          counters: %{atom() => non_neg_integer()}
        }

  @doc """
  A session `id` of ground station `identity` seeing `vehicles` (`%{sysid => %{id,
  board}}`), started at `now_ms`. Option: `timeout_ms` (#{@default_timeout_ms}: silence that
  ends it).
  """
  @spec new(
          String.t(),
          identity(),
          %{(1..255) => %{id: String.t(), board: atom()}},
          integer(),
          keyword()
        ) :: t()
  def new(id, identity, vehicles, now_ms, opts \\ []) do
    vehicles =
      Map.new(vehicles, fn {sysid, v} ->
        {sysid,
         %{
           id: v.id,
           board: v.board,
           # whether the vehicle arms itself (its board's own commands), or is armed while
           # a pilot holds the helm
           arms: Neptunus.Vehicle.Board.own_commands?(v.board),
           view: nil,
           pilot: false,
           epoch: nil,
           last_axes: nil,
           asked: false,
           awaiting_helm: false
         }}
      end)

    %__MODULE__{
      id: id,
      identity: identity,
      vehicles: vehicles,
      last_heard_ms: now_ms,
      timeout_ms: Keyword.get(opts, :timeout_ms, @default_timeout_ms)
    }
  end

  @doc "This session's party id on the helm (`Neptunus.GCS.Party`)."
  @spec party_id(t()) :: String.t()
  def party_id(%__MODULE__{gcs: gcs, id: id}), do: Party.id(sysid_of(gcs), id)

  @doc "This session's name as the helm shows it to others."
  @spec party_name(t()) :: String.t()
  def party_name(%__MODULE__{gcs: gcs, identity: identity}),
    do: "#{identity.name} (GCS #{sysid_of(gcs)})"

  defp sysid_of(nil), do: 0
  defp sysid_of({sysid, _}), do: sysid

  @doc "The ground station's system id (0 until it has spoken)."
  @spec gcs_sysid(t()) :: byte()
  def gcs_sysid(%__MODULE__{gcs: gcs}), do: sysid_of(gcs)

  @doc "Counts one event of `kind` (the shell counts what never reaches the core)."
  @spec count(t(), atom()) :: t()
  def count(%__MODULE__{counters: c} = s, kind),
    do: %{s | counters: Map.update(c, kind, 1, &(&1 + 1))}

  @doc "Which vehicles this session pilots (their system ids)."
  @spec piloting(t()) :: [1..255]
  def piloting(s), do: for({sysid, %{pilot: true}} <- s.vehicles, do: sysid)

  @doc "Applies an event (see the moduledoc)."
  @spec handle(t(), term()) :: {t(), [action()]}
  def handle(%__MODULE__{} = s, {:message, message, now_ms}) do
    s = %{s | last_heard_ms: now_ms}

    cond do
      s.gcs == nil ->
        s = %{s | gcs: {message.system, message.component}}
        message(count(s, :messages), message, now_ms)

      elem(s.gcs, 0) != message.system ->
        {count(s, :foreign), []}

      true ->
        message(count(s, :messages), message, now_ms)
    end
  end

  def handle(s, {:vehicle, sysid, view}) do
    case s.vehicles do
      %{^sysid => v} ->
        me = party_id(s)

        v =
          case view.helm do
            # a view taken before the grant (or trip) this session already knows of: the helm
            # only moves forward (its epoch never goes down), so an older one is not news
            %{epoch: epoch} when is_integer(v.epoch) and epoch < v.epoch ->
              %{v | view: %{view | helm: v.view && v.view.helm}}

            %{pilot: %{id: ^me}, epoch: epoch} ->
              %{v | view: view, pilot: true, epoch: epoch}

            %{pilot: _} ->
              %{v | view: view, pilot: false, asked: false}

            _ ->
              %{v | view: view}
          end

        {put_vehicle(s, sysid, v), []}

      _ ->
        {s, []}
    end
  end

  def handle(s, {:helm, sysid, event, payload}), do: helm_event(s, sysid, event, payload)

  def handle(s, {:result, ref, result}) do
    case Map.pop(s.pending, ref) do
      {nil, _} -> {s, []}
      {context, pending} -> result(%{s | pending: pending}, context, result)
    end
  end

  def handle(s, {:check, now_ms}) do
    if now_ms - s.last_heard_ms > s.timeout_ms, do: {s, [:close]}, else: {s, []}
  end

  @doc """
  The streamed messages of vehicle `sysid` due for this ground station at `now_ms`, of those
  the vehicle has at this tick (`available`, names): `{session, names}`.
  """
  @spec due(t(), 1..255, [atom()], integer()) :: {t(), [atom()]}
  def due(s, sysid, available, now_ms) do
    {scheduler, names} = Scheduler.due(s.scheduler, sysid, available, now_ms)
    {%{s | scheduler: scheduler}, names}
  end

  # ---- messages ------------------------------------------------------------------------------

  defp message(s, %{name: :heartbeat}, _now) do
    # the ground station's heartbeat feeds the deadman of every helm it holds
    {s, for(sysid <- piloting(s), do: {:intent, 0, sysid, :heartbeat})}
  end

  defp message(s, %{name: :manual_control, fields: %{target: target} = f}, _now),
    do: stick(s, target, Manual.axes(f), :manual_control)

  defp message(s, %{name: :rc_channels_override, fields: f}, _now),
    do: stick(s, f.target_system, Manual.rc_axes(f), :rc_channels_override)

  defp message(s, %{name: :command_long, fields: f}, now) do
    params = [f.param1, f.param2, f.param3, f.param4, f.param5, f.param6, f.param7]
    command(s, f.target_system, f.command, params, now)
  end

  defp message(s, %{name: :command_int, fields: f}, now) do
    params = [f.param1, f.param2, f.param3, f.param4, f.x, f.y, f.z]
    command(s, f.target_system, f.command, params, now)
  end

  defp message(s, %{name: :set_mode, fields: f}, _now) do
    with_vehicle(s, f.target_system, fn sysid, v ->
      if Bitwise.band(f.base_mode, 1) == 1,
        do: set_mode(s, sysid, v, f.custom_mode, 11),
        else:
          ack(s, sysid, 11, @unsupported, "only custom modes (MAV_MODE_FLAG_CUSTOM_MODE_ENABLED)")
    end)
  end

  defp message(s, %{name: :param_request_list, fields: f}, _now) do
    with_vehicle(s, f.target_system, fn sysid, _v -> intent(s, sysid, :params, :param_list) end)
  end

  defp message(s, %{name: :param_request_read, fields: f}, _now) do
    with_vehicle(s, f.target_system, fn sysid, _v ->
      intent(s, sysid, :params, {:param_read, f.param_id, f.param_index})
    end)
  end

  defp message(s, %{name: :param_set, fields: f}, _now) do
    with_vehicle(s, f.target_system, fn sysid, v ->
      name = f.param_id

      case Params.set(name, f.param_value) do
        {:error, "no parameter " <> _ = reason} ->
          {s, statustext(s, sysid, @warning, "#{v.id}: #{reason}")}

        {:error, reason} ->
          # the value stays: the ground station is told the one in force
          intent(s, sysid, :params, {:param_read, name, -1, reason})

        {:control, _, _} = set ->
          if v.pilot,
            do: intent(s, sysid, {:param_set, name, set}, {:param_set, name}),
            else: intent(s, sysid, :params, {:param_read, name, -1, @not_in_control})

        {:tune, _} = set ->
          if v.pilot or s.identity.role == :main_station,
            do: intent(s, sysid, {:param_set, name, set}, {:param_set, name}),
            else:
              intent(
                s,
                sysid,
                :params,
                {:param_read, name, -1, "tuning is for the pilot or the main station"}
              )
      end
    end)
  end

  defp message(s, %{name: :request_data_stream, fields: f}, _now) do
    with_vehicle(s, f.target_system, fn sysid, _v ->
      scheduler =
        Scheduler.data_stream(
          s.scheduler,
          sysid,
          f.req_stream_id,
          f.req_message_rate,
          f.start_stop == 1
        )

      {%{s | scheduler: scheduler}, []}
    end)
  end

  defp message(s, %{name: :mission_request_list, fields: f}, _now) do
    # no missions here: an empty list of the type asked for, to the station that asked
    with_vehicle(s, f.target_system, fn sysid, _v ->
      fields = Map.merge(to_station(s), %{count: 0, mission_type: f.mission_type})
      {s, [send(s, sysid, :mission_count, fields)]}
    end)
  end

  defp message(s, %{name: :timesync, fields: %{tc1: 0, ts1: ts1}}, now) do
    # a request: answered by every vehicle with its clock (ns)
    {s,
     for sysid <- Map.keys(s.vehicles) do
       {:send, sysid, :timesync, %{tc1: now * 1_000_000, ts1: ts1}}
     end}
  end

  defp message(s, _message, _now), do: {count(s, :ignored), []}

  # ---- the sticks ----------------------------------------------------------------------------

  defp stick(s, target, axes, kind) do
    case Map.fetch(s.vehicles, target) do
      {:ok, %{pilot: true} = v} ->
        s = count(s, :manual_applied)

        if axes == v.last_axes do
          {s, [{:intent, 0, target, :heartbeat}]}
        else
          v = %{v | last_axes: axes}
          s = put_vehicle(s, target, v)
          intent(s, target, {:thrust, axes, v.epoch}, {:thrust, axes})
        end

      {:ok, v} ->
        if s.identity.trusted and free?(v) and not v.awaiting_helm do
          # a trusted ground station takes a free helm with its stick; its next input flies
          s = put_vehicle(s, target, %{v | awaiting_helm: true})
          intent(s, target, :request_control, {:take, kind})
        else
          {count(s, :manual_ignored), []}
        end

      :error ->
        {count(s, :manual_ignored), []}
    end
  end

  defp free?(%{view: %{helm: %{state: "free"}}}), do: true
  defp free?(_v), do: false

  # ---- commands ------------------------------------------------------------------------------

  defp command(s, target, command, params, _now) do
    with_vehicle(s, target, fn sysid, v ->
      s = count(s, :commands)
      run_command(s, sysid, v, command, params)
    end)
  end

  defp run_command(s, sysid, _v, @arm_disarm, [p1 | _]) when p1 not in [0.0, 1.0],
    do: ack(s, sysid, @arm_disarm, @denied, "param1 must be 1 (arm) or 0 (disarm)")

  defp run_command(s, sysid, v, @arm_disarm, [p1 | _]) do
    arm? = p1 == 1.0

    cond do
      not v.pilot and arm? and s.identity.trusted and free?(v) ->
        intent(s, sysid, :request_control, :take_then_arm)

      not v.pilot ->
        ack(s, sysid, @arm_disarm, @denied, @not_in_control)

      v.arms ->
        intent(s, sysid, {:arm, arm?}, {:ack, @arm_disarm})

      arm? ->
        # a board without arming: armed while a pilot holds the helm, which this one does
        ack(s, sysid, @arm_disarm, @accepted, nil)

      true ->
        # disarming gives the helm up (the vehicle stops)
        intent(s, sysid, :release_control, {:ack, @arm_disarm})
    end
  end

  defp run_command(s, sysid, v, @do_set_mode, [base, custom | _]) do
    if is_number(base) and Bitwise.band(trunc(base), 1) == 1 and is_number(custom),
      do: set_mode(s, sysid, v, trunc(custom), @do_set_mode),
      else: ack(s, sysid, @do_set_mode, @unsupported, "only custom modes (param1 has bit 1 set)")
  end

  defp run_command(s, sysid, v, @do_set_servo, [servo, us | _]) do
    case {servo, us} do
      {servo, us} when servo == @lights_servo and is_number(us) ->
        lights = round((us - 1100) / 800 * 255) |> max(0) |> min(255)
        control(s, sysid, v, @do_set_servo, [{"set_lights", %{"value" => lights}}])

      {servo, us} when servo == @tilt_servo and is_number(us) ->
        tilt = (us - 1500) / 400 * :math.pi() / 4
        control(s, sysid, v, @do_set_servo, [{"set_tilt", %{"value" => tilt}}])

      _ ->
        ack(
          s,
          sysid,
          @do_set_servo,
          @unsupported,
          "servo #{inspect(servo)} is neither the lights (9) nor the camera tilt (8)"
        )
    end
  end

  defp run_command(s, sysid, v, command, [pitch | _])
       when command in [@do_mount_control, @do_gimbal_pitchyaw] do
    if is_number(pitch),
      do:
        control(s, sysid, v, command, [
          {"set_tilt", %{"value" => pitch * :math.pi() / 180}}
        ]),
      else: ack(s, sysid, command, @denied, "the pitch must be a number (degrees)")
  end

  defp run_command(s, sysid, _v, @set_message_interval, [id, interval | _]) do
    with true <- is_number(id) and is_number(interval),
         {:ok, scheduler} <- Scheduler.set_interval(s.scheduler, sysid, trunc(id), interval) do
      ack(%{s | scheduler: scheduler}, sysid, @set_message_interval, @accepted, nil)
    else
      {:error, reason} -> ack(s, sysid, @set_message_interval, @denied, reason)
      false -> ack(s, sysid, @set_message_interval, @denied, "bad message id or interval")
    end
  end

  defp run_command(s, sysid, _v, @get_message_interval, [id | _]) do
    case is_number(id) and Scheduler.interval_us(s.scheduler, sysid, trunc(id)) do
      us when is_integer(us) ->
        {s, actions} = ack(s, sysid, @get_message_interval, @accepted, nil)

        {s,
         actions ++ [send(s, sysid, :message_interval, %{message_id: trunc(id), interval_us: us})]}

      {:error, reason} ->
        ack(s, sysid, @get_message_interval, @denied, reason)

      false ->
        ack(s, sysid, @get_message_interval, @denied, "bad message id")
    end
  end

  defp run_command(s, sysid, v, @request_message, [id | _]) do
    case is_number(id) and trunc(id) do
      148 ->
        {s, actions} = ack(s, sysid, @request_message, @accepted, nil)
        {s, actions ++ [{:frames, sysid, [:autopilot_version]}]}

      id when is_integer(id) ->
        case Scheduler.streamed_name(id) do
          {:ok, name} ->
            case v.view do
              %{messages: messages} when is_list(messages) ->
                if name in messages do
                  {s, actions} = ack(s, sysid, @request_message, @accepted, nil)
                  {s, actions ++ [{:frames, sysid, [name]}]}
                else
                  # ArduPilot's answer to a message it cannot send now
                  ack(s, sysid, @request_message, @failed, unavailable(name))
                end

              _ ->
                {s, actions} = ack(s, sysid, @request_message, @accepted, nil)
                {s, actions ++ [{:frames, sysid, [name]}]}
            end

          {:error, _} ->
            ack(
              s,
              sysid,
              @request_message,
              @unsupported,
              "message #{id} cannot be requested here"
            )
        end

      false ->
        ack(s, sysid, @request_message, @denied, "bad message id")
    end
  end

  defp run_command(s, sysid, _v, @request_capabilities, _params) do
    {s, actions} = ack(s, sysid, @request_capabilities, @accepted, nil)
    {s, actions ++ [{:frames, sysid, [:autopilot_version]}]}
  end

  defp run_command(s, sysid, v, @request_operator_control, [_sysid, action, allow | _]) do
    cond do
      action == 0.0 ->
        intent(s, sysid, :release_control, {:ack, @request_operator_control})

      action != 1.0 ->
        ack(
          s,
          sysid,
          @request_operator_control,
          @denied,
          "action must be 0 (release) or 1 (request)"
        )

      v.pilot and v.asked ->
        # the pilot answers a request for its helm: allow takeover gives it, else refuses
        intent(s, sysid, {:answer, allow == 1.0}, {:ack, @request_operator_control})

      v.pilot ->
        ack(s, sysid, @request_operator_control, @accepted, nil)

      s.identity.role == :main_station ->
        intent(s, sysid, :take_control, {:control_request, :take})

      true ->
        intent(s, sysid, :request_control, {:control_request, :request})
    end
  end

  defp run_command(s, sysid, _v, command, _params),
    do: ack(s, sysid, command, @unsupported, nil)

  defp set_mode(s, sysid, v, custom_mode, command) do
    control =
      case v.view do
        %{control: control} -> control
        _ -> nil
      end

    cond do
      not v.pilot ->
        ack(s, sysid, command, @denied, @not_in_control)

      true ->
        case Modes.commands(custom_mode, control) do
          {:ok, []} -> ack(s, sysid, command, @accepted, nil)
          {:ok, commands} -> intent(s, sysid, {:commands, commands}, {:ack, command})
          {:error, reason} -> ack(s, sysid, command, @denied, reason)
        end
    end
  end

  # a pilot-only control command, acknowledged with its result
  defp control(s, sysid, v, command, commands) do
    if v.pilot,
      do: intent(s, sysid, {:commands, commands}, {:ack, command}),
      else: ack(s, sysid, command, @denied, @not_in_control)
  end

  # ---- the helm's events ---------------------------------------------------------------------

  defp helm_event(s, sysid, "control_granted", payload) do
    case s.vehicles do
      %{^sysid => v} ->
        epoch = payload[:epoch] || v.epoch
        v = %{v | pilot: true, epoch: epoch, asked: false, awaiting_helm: false, last_axes: nil}
        s = put_vehicle(s, sysid, v)
        text = statustext(s, sysid, @notice, "#{v.id}: you have the helm")
        {s, acks} = finish_control_request(s, sysid, @accepted, nil)
        {s, text ++ acks}

      _ ->
        {s, []}
    end
  end

  defp helm_event(s, sysid, "control_lost", payload) do
    case s.vehicles do
      %{^sysid => v} ->
        s = put_vehicle(s, sysid, %{v | pilot: false, asked: false, last_axes: nil})
        {s, statustext(s, sysid, @warning, "#{v.id}: helm lost (#{payload[:reason]})")}

      _ ->
        {s, []}
    end
  end

  defp helm_event(s, sysid, "control_request", payload) do
    case s.vehicles do
      %{^sysid => v} ->
        from = payload[:from] || %{}
        requester = Party.sysid(from[:id]) || 0
        timeout_s = helm_timeout_s(v)
        s = put_vehicle(s, sysid, %{v | asked: true})

        fields = %{
          command: @request_operator_control,
          confirmation: 0,
          param1: requester * 1.0,
          param2: 1.0,
          param3: 0.0,
          param4: timeout_s * 1.0,
          param5: 0.0,
          param6: 0.0,
          param7: 0.0
        }

        notify = send(s, sysid, :command_long, Map.merge(fields, to_station(s)))

        text =
          "#{v.id}: #{from[:name] || "someone"} asks for the helm; allow: command 32100 " <>
            "with params 1, 1 (allow takeover); refuse: 1, 0"

        {s, [notify | statustext(s, sysid, @warning, text)]}

      _ ->
        {s, []}
    end
  end

  defp helm_event(s, sysid, "request_denied", payload) do
    reason = "control request denied: #{payload[:reason] || "denied"}"
    finish_control_request(s, sysid, @denied, reason)
  end

  defp helm_event(s, _sysid, _event, _payload), do: {s, []}

  defp helm_timeout_s(%{view: %{helm: %{request_timeout_ms: ms}}}) when is_integer(ms),
    do: max(3, min(60, div(ms, 1000)))

  defp helm_timeout_s(_v), do: 10

  # the final ACK of a request for the helm whose first ACK said IN_PROGRESS
  defp finish_control_request(s, sysid, result, reason) do
    case Enum.find(s.pending, fn {_ref, c} -> c == {:awaiting_helm, sysid} end) do
      {ref, _} ->
        s = %{s | pending: Map.delete(s.pending, ref)}
        ack(s, sysid, @request_operator_control, result, reason)

      nil ->
        {s, []}
    end
  end

  # why a streamed message cannot be sent now (REQUEST_MESSAGE)
  defp unavailable(:global_position_int),
    do: "GLOBAL_POSITION_INT: the vehicle has no valid position with a geodetic origin"

  defp unavailable(:local_position_ned),
    do: "LOCAL_POSITION_NED: the vehicle has no valid position"

  defp unavailable(name),
    do: "#{name |> Atom.to_string() |> String.upcase()}: not known yet"

  # ---- results -------------------------------------------------------------------------------

  defp result(s, {:thrust, _axes}, {:error, reason}, sysid)
       when reason in ["stale_command", "missing field: epoch"] do
    # the helm moved on (a deadman trip, a new grant): learn its epoch; the next input
    # goes again
    v = s.vehicles[sysid]
    s = put_vehicle(s, sysid, %{v | last_axes: nil})
    intent(s, sysid, :status, :refresh_epoch)
  end

  defp result(s, {:thrust, _axes}, {:error, _reason}, sysid) do
    v = s.vehicles[sysid]
    {put_vehicle(s, sysid, %{v | last_axes: nil}), []}
  end

  defp result(s, {:thrust, _axes}, {:ok, _}, _sysid), do: {s, []}

  defp result(s, :refresh_epoch, {:ok, %{epoch: epoch}}, sysid) do
    v = s.vehicles[sysid]
    {put_vehicle(s, sysid, %{v | epoch: epoch}), []}
  end

  defp result(s, :refresh_epoch, _result, _sysid), do: {s, []}

  defp result(s, {:ack, command}, {:ok, _}, sysid), do: ack(s, sysid, command, @accepted, nil)

  defp result(s, {:ack, command}, {:error, reason}, sysid),
    do: ack(s, sysid, command, refusal(reason), reason)

  defp result(s, {:take, _kind}, result, sysid) do
    v = s.vehicles[sysid]
    s = put_vehicle(s, sysid, %{v | awaiting_helm: false})

    case result do
      {:ok, %{status: "granted", grant: grant}} -> {granted(s, sysid, grant), []}
      _ -> {count(s, :manual_ignored), []}
    end
  end

  defp result(s, :take_then_arm, {:ok, %{status: "granted", grant: grant}}, sysid) do
    s = granted(s, sysid, grant)
    run_command(s, sysid, s.vehicles[sysid], @arm_disarm, [1.0])
  end

  defp result(s, :take_then_arm, result, sysid) do
    reason =
      case result do
        {:error, reason} -> reason
        _ -> "the helm is not free"
      end

    ack(s, sysid, @arm_disarm, @denied, reason)
  end

  defp result(s, {:control_request, _how}, {:ok, %{status: "granted", grant: grant}}, sysid) do
    ack(granted(s, sysid, grant), sysid, @request_operator_control, @accepted, nil)
  end

  defp result(s, {:control_request, _how}, {:ok, %{status: status} = reply}, sysid)
       when status in ["pending", "takeover"] do
    if s.vehicles[sysid].pilot,
      # the helm came already (its event overtook this reply)
      do: ack(s, sysid, @request_operator_control, @accepted, nil),
      else: awaiting_helm(s, sysid, reply)
  end

  defp result(s, {:control_request, _how}, {:error, reason}, sysid),
    do: ack(s, sysid, @request_operator_control, refusal(reason), reason)

  defp result(s, {:param_set, name}, {:ok, sources}, sysid) do
    {s, param_values(s, sysid, sources, [name])}
  end

  defp result(s, {:param_set, name}, {:error, reason, sources}, sysid) do
    {s,
     param_values(s, sysid, sources, [name]) ++
       statustext(s, sysid, @warning, "#{s.vehicles[sysid].id}: #{name} refused: #{reason}")}
  end

  defp result(s, :param_list, {:ok, sources}, sysid),
    do: {s, param_values(s, sysid, sources, :all)}

  defp result(s, {:param_read, name, index}, {:ok, sources}, sysid),
    do: result(s, {:param_read, name, index, nil}, {:ok, sources}, sysid)

  defp result(s, {:param_read, name, index, reason}, {:ok, sources}, sysid) do
    params = Params.list(sources)

    selected =
      cond do
        index >= 0 -> params |> Enum.at(index) |> List.wrap() |> Enum.map(& &1.name)
        true -> [name]
      end

    refused =
      if reason,
        do: statustext(s, sysid, @warning, "#{s.vehicles[sysid].id}: #{name} refused: #{reason}"),
        else: []

    {s, param_values(s, sysid, sources, selected) ++ refused}
  end

  defp result(s, _context, {:error, reason}, sysid) when is_binary(reason),
    do: {s, statustext(s, sysid, @warning, "#{s.vehicles[sysid].id}: #{reason}")}

  defp result(s, _context, _result, _sysid), do: {s, []}

  # asked of the pilot (or the takeover countdown runs): the helm's event finishes it
  defp awaiting_helm(s, sysid, reply) do
    {s, actions} = ack(s, sysid, @request_operator_control, @in_progress, nil)
    ref = s.next_ref
    s = %{s | next_ref: ref + 1, pending: Map.put(s.pending, ref, {:awaiting_helm, sysid})}

    wait =
      case reply do
        %{timeout_ms: ms} ->
          "#{s.vehicles[sysid].id}: control requested, the pilot is asked (#{div(ms, 1000)} s)"

        %{countdown_ms: ms} ->
          "#{s.vehicles[sysid].id}: taking over in #{Float.round(ms / 1000, 1)} s"

        _ ->
          "#{s.vehicles[sysid].id}: control requested"
      end

    {s, actions ++ statustext(s, sysid, @info, wait)}
  end

  defp result(s, context, result) do
    {sysid, context} = context
    result(s, context, result, sysid)
  end

  defp granted(s, sysid, grant) do
    v = s.vehicles[sysid]
    put_vehicle(s, sysid, %{v | pilot: true, epoch: grant[:epoch] || v.epoch, last_axes: nil})
  end

  # the helm's refusals as MAV_RESULTs: "busy", "vehicle restarting" may pass; the rest not
  defp refusal("busy"), do: @temporarily_rejected
  defp refusal("no_request"), do: @failed
  defp refusal("vehicle restarting" <> _), do: @temporarily_rejected
  defp refusal(_), do: @denied

  defp param_values(s, sysid, sources, which) do
    params = Params.list(sources)
    count = length(params)

    params
    |> Enum.with_index()
    |> Enum.filter(fn {p, _} -> which == :all or p.name in which end)
    |> Enum.map(fn {p, i} ->
      send(s, sysid, :param_value, %{
        param_id: p.name,
        param_value: p.value,
        param_type: Params.type(),
        param_count: count,
        param_index: i
      })
    end)
  end

  # ---- helpers -------------------------------------------------------------------------------

  # the vehicle a message is for: its system id, or 0 on a node with one vehicle
  defp with_vehicle(s, target, fun) do
    target =
      case {target, map_size(s.vehicles)} do
        {0, 1} -> s.vehicles |> Map.keys() |> hd()
        {target, _} -> target
      end

    case s.vehicles do
      %{^target => v} -> fun.(target, v)
      _ -> {count(s, :not_ours), []}
    end
  end

  defp intent(s, sysid, intent, context) do
    if map_size(s.pending) >= @max_pending and slow?(intent) do
      s = count(s, :overloaded)

      case context do
        {:ack, command} ->
          ack(s, sysid, command, @temporarily_rejected, "too many commands waiting")

        _ ->
          {s, []}
      end
    else
      ref = s.next_ref
      pending = Map.put(s.pending, ref, {sysid, context})
      {%{s | next_ref: ref + 1, pending: pending}, [{:intent, ref, sysid, intent}]}
    end
  end

  @doc "Whether an intent may take long (the shell runs it off the session's process)."
  @spec slow?(intent()) :: boolean()
  def slow?({:thrust, _, _}), do: false
  def slow?(:heartbeat), do: false
  def slow?(:status), do: false
  def slow?(_intent), do: true

  defp ack(s, sysid, command, result, reason) do
    fields = %{command: command, result: result, progress: 0, result_param2: 0}
    ack = send(s, sysid, :command_ack, Map.merge(fields, to_station(s)))

    s = if result in [@accepted, @in_progress], do: s, else: count(s, :refused)

    text =
      if reason,
        do: statustext(s, sysid, @warning, "#{s.vehicles[sysid].id}: #{reason}"),
        else: []

    {s, [ack | text]}
  end

  defp send(_s, sysid, name, fields), do: {:send, sysid, name, fields}

  # the address of a message meant for this session's station (its ids from its first message)
  defp to_station(s) do
    {system, component} = s.gcs || {0, 0}
    %{target_system: system, target_component: component}
  end

  defp statustext(_s, sysid, severity, text), do: [{:text, sysid, severity, text}]

  defp put_vehicle(s, sysid, v), do: %{s | vehicles: Map.put(s.vehicles, sysid, v)}
end
