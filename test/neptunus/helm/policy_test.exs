defmodule Neptunus.Helm.PolicyTest do
  # Every helm state × every event × every kind of sender, each with its expected reply, next
  # state and actions; then invariants that must hold for all of them.
  use ExUnit.Case, async: true

  alias Neptunus.Helm.Policy

  @deadman 500
  @t0 10_000

  @parties %{
    a: %{id: "a", name: "Ada", role: :pilot},
    b: %{id: "b", name: "Bob", role: :pilot},
    c: %{id: "c", name: "Cy", role: :pilot},
    m: %{id: "m", name: "Main", role: :main_station},
    m2: %{id: "m2", name: "Main", role: :main_station},
    o: %{id: "o", name: "Olga", role: :observer}
  }
  @senders Map.keys(@parties)

  defp p(key), do: Map.fetch!(@parties, key)

  # The states, each with a pilot who was last heard at @t0 and epoch 7.
  @states [
    :free,
    {:piloted, :a},
    {:piloted, :m},
    {:requested, :a, :b},
    {:requested, :a, :m},
    {:takeover, :a, :m}
  ]

  defp policy(:free), do: %Policy{helm: :free, epoch: 7}

  defp policy(state),
    do: %Policy{helm: resolve(state), epoch: 7, last_seen_ms: @t0, tripped: false}

  @events [
    :request,
    :accept,
    :deny,
    :take,
    :release,
    :heartbeat,
    :stop_command,
    :thrust_current,
    :thrust_stale,
    :thrust_unstamped,
    :thrust_bad_stamp,
    :leave_pilot_disconnected,
    :leave_pilot_left,
    :request_timeout,
    :takeover_due,
    :tick_quiet,
    :tick_silent
  ]

  # {event, now}: ticks come 100 ms (quiet) or 600 ms (silent) after the pilot was last heard.
  defp event(:request, s), do: {{:request, p(s)}, @t0 + 50}
  defp event(:accept, s), do: {{:answer, p(s), true}, @t0 + 50}
  defp event(:deny, s), do: {{:answer, p(s), false}, @t0 + 50}
  defp event(:take, s), do: {{:take, p(s)}, @t0 + 50}
  defp event(:release, s), do: {{:release, p(s)}, @t0 + 50}
  defp event(:heartbeat, s), do: {{:heartbeat, p(s)}, @t0 + 50}
  defp event(:stop_command, s), do: {{:command, p(s), :none}, @t0 + 50}
  defp event(:thrust_current, s), do: {{:command, p(s), {:epoch, 7}}, @t0 + 50}
  defp event(:thrust_stale, s), do: {{:command, p(s), {:epoch, 6}}, @t0 + 50}
  defp event(:thrust_unstamped, s), do: {{:command, p(s), {:epoch, nil}}, @t0 + 50}
  defp event(:thrust_bad_stamp, s), do: {{:command, p(s), {:epoch, "7"}}, @t0 + 50}

  defp event(:leave_pilot_disconnected, s),
    do: {{:leave, p(s).id, "pilot_disconnected"}, @t0 + 50}

  defp event(:leave_pilot_left, s), do: {{:leave, p(s).id, "pilot_left"}, @t0 + 50}
  defp event(:request_timeout, _s), do: {:request_timeout, @t0 + 50}
  defp event(:takeover_due, _s), do: {:takeover_due, @t0 + 50}
  defp event(:tick_quiet, _s), do: {{:tick, @deadman}, @t0 + 100}
  defp event(:tick_silent, _s), do: {{:tick, @deadman}, @t0 + 600}

  # How the sender relates to the state: :pilot, :second (requester or main station taking
  # over) or :other.
  defp relation(:free, _s), do: :other
  defp relation({:piloted, x}, s), do: if(x == s, do: :pilot, else: :other)

  defp relation({_, x, y}, s) do
    cond do
      x == s -> :pilot
      y == s -> :second
      true -> :other
    end
  end

  defp pilot_key(:free), do: nil
  defp pilot_key(state), do: elem(state, 1)
  defp second_key({_, _, y}), do: y
  defp second_key(_), do: nil

  # -- the specification ----------------------------------------------------------------------
  # expected(state, event, sender) :: {reply, next_state (keys), actions (keys), epoch_delta}

  @timers [:request_timeout, :takeover_due]
  @commands [
    :heartbeat,
    :stop_command,
    :thrust_current,
    :thrust_stale,
    :thrust_unstamped,
    :thrust_bad_stamp
  ]

  defp expected(state, event, s) do
    rel = relation(state, s)
    role = p(s).role
    pilot = pilot_key(state)
    second = second_key(state)

    case {state, event, rel, role} do
      # ---- the pilot's own messages, in every state with a pilot
      {_, :heartbeat, :pilot, _} ->
        same(state, :ok)

      {_, e, :pilot, _} when e in [:stop_command, :thrust_current] ->
        {:ok, state, [:run], 0}

      {_, :thrust_stale, :pilot, _} ->
        same(state, {:error, "stale_command"})

      {_, :thrust_unstamped, :pilot, _} ->
        same(state, {:error, "missing field: epoch"})

      {_, :thrust_bad_stamp, :pilot, _} ->
        same(state, {:error, "epoch must be an integer (from the grant)"})

      # ---- nobody else commands, anywhere
      {_, e, _, _} when e in @commands ->
        same(state, {:error, "not_in_control"})

      # ---- request_control
      {_, :request, _, :observer} ->
        same(state, {:error, "forbidden"})

      {:free, :request, _, _} ->
        granted(s)

      {_, :request, :pilot, _} ->
        same(state, {:ok, :in_control})

      {{:piloted, _}, :request, :other, _} ->
        {{:ok, :pending}, {:requested, pilot, s},
         [{:push, pilot, "control_request", %{from: p(s)}}, :changed], 0}

      {{:requested, _, _}, :request, :second, _} ->
        same(state, {:ok, :pending})

      {{:takeover, _, _}, :request, :second, _} ->
        same(state, {:ok, :takeover})

      {_, :request, :other, _} ->
        same(state, {:error, "busy"})

      # ---- answer_request
      {{:requested, _, _}, :accept, :pilot, _} ->
        transferred(pilot, second, "control_transferred")

      {{:requested, _, _}, :deny, :pilot, _} ->
        {:ok, {:piloted, pilot},
         [{:push, second, "request_denied", %{reason: "denied"}}, :changed], 0}

      {_, e, :pilot, _} when e in [:accept, :deny] ->
        same(state, {:error, "no_request"})

      {_, e, _, _} when e in [:accept, :deny] ->
        same(state, {:error, "not_in_control"})

      # ---- take_control
      {_, :take, _, role} when role != :main_station ->
        same(state, {:error, "forbidden"})

      {:free, :take, _, _} ->
        granted(s)

      {_, :take, :pilot, _} ->
        same(state, {:ok, :in_control})

      {{:piloted, _}, :take, :other, _} ->
        {{:ok, :takeover}, {:takeover, pilot, s}, [:changed], 0}

      {{:requested, _, _}, :take, :second, _} ->
        {{:ok, :takeover}, {:takeover, pilot, s}, [:changed], 0}

      {{:requested, _, _}, :take, :other, _} ->
        {{:ok, :takeover}, {:takeover, pilot, s},
         [{:push, second, "request_denied", %{reason: "main_station_takeover"}}, :changed], 0}

      {{:takeover, _, _}, :take, :second, _} ->
        same(state, {:ok, :takeover})

      {{:takeover, _, _}, :take, :other, _} ->
        same(state, {:error, "busy"})

      # ---- release_control
      {{:piloted, _}, :release, :pilot, _} ->
        freed(pilot, "released")

      {_, :release, :pilot, _} ->
        transferred(pilot, second, "released")

      {_, :release, :second, _} ->
        {:ok, {:piloted, pilot}, [:changed], 0}

      {_, :release, :other, _} ->
        same(state, {:error, "not_in_control"})

      # ---- a connection closes or leaves
      {_, leave, rel, _} when leave in [:leave_pilot_disconnected, :leave_pilot_left] ->
        reason = if leave == :leave_pilot_left, do: "pilot_left", else: "pilot_disconnected"

        case {state, rel} do
          {{:piloted, _}, :pilot} -> freed(pilot, reason)
          {_, :pilot} -> transferred(pilot, second, reason)
          {_, :second} -> {:ok, {:piloted, pilot}, [:changed], 0}
          {_, :other} -> same(state, :ok)
        end

      # ---- timers
      {{:requested, _, _}, :request_timeout, _, _} ->
        {:ok, {:piloted, pilot},
         [{:push, second, "request_denied", %{reason: "request_timeout"}}, :changed], 0}

      {{:takeover, _, _}, :takeover_due, _, _} ->
        transferred(pilot, second, "main_station_takeover")

      {_, e, _, _} when e in @timers ->
        same(state, :ok)

      # ---- deadman
      {:free, _tick, _, _} ->
        same(state, :ok)

      {_, :tick_quiet, _, _} ->
        same(state, :ok)

      {_, :tick_silent, _, _} ->
        {:ok, state, [{:stop, "deadman"}, :changed], 1}
    end
  end

  defp same(state, reply), do: {reply, state, [], 0}
  defp granted(s), do: {{:ok, :granted}, {:piloted, s}, [{:grant, s}, :changed], 1}

  defp transferred(from, to, reason),
    do:
      {:ok, {:piloted, to}, [{:stop, reason}, {:revoke, from, reason}, {:grant, to}, :changed], 1}

  defp freed(pilot, reason),
    do: {:ok, :free, [{:stop, reason}, {:revoke, pilot, reason}, :changed], 0}

  defp resolve(:free), do: :free
  defp resolve({kind, x}), do: {kind, p(x)}
  defp resolve({kind, x, y}), do: {kind, p(x), p(y)}

  defp resolve_action({:push, k, e, payload}), do: {:push, p(k), e, payload}
  defp resolve_action({:grant, k}), do: {:grant, p(k)}
  defp resolve_action({:revoke, k, r}), do: {:revoke, p(k), r}
  defp resolve_action(other), do: other

  # -- the matrix -----------------------------------------------------------------------------

  for state <- @states, event <- @events do
    @state state
    @event event
    test "#{inspect(state)} × #{event}, from each kind of sender" do
      for sender <- @senders do
        {reply, next, actions, epoch_delta} = expected(@state, @event, sender)
        before = policy(@state)
        {ev, now} = event(@event, sender)
        {got_reply, after_, got_actions} = Policy.handle(before, ev, now)
        where = "#{inspect(@state)} × #{inspect(ev)}"

        assert got_reply == reply, where
        assert after_.helm == resolve(next), where
        assert got_actions == Enum.map(actions, &resolve_action/1), where
        assert after_.epoch == before.epoch + epoch_delta, where
      end
    end
  end

  # -- invariants over the whole matrix -------------------------------------------------------

  defp all_outcomes do
    for state <- @states, event <- @events, sender <- @senders do
      before = policy(state)
      {ev, now} = event(event, sender)
      {reply, after_, actions} = Policy.handle(before, ev, now)

      %{state: state, event: event, sender: sender, ev: ev, now: now, before: before}
      |> Map.merge(%{reply: reply, after: after_, actions: actions})
    end
  end

  test "a refused event changes nothing and does nothing" do
    for %{reply: {:error, _}} = o <- all_outcomes() do
      assert o.actions == [], inspect(o)
      assert o.after.helm == o.before.helm, inspect(o)
      assert o.after.epoch == o.before.epoch, inspect(o)
    end
  end

  test "a new pilot always comes with a new epoch, a grant, and neutral thrusters first" do
    for o <- all_outcomes(), Policy.pilot(o.after) != Policy.pilot(o.before) do
      new = Policy.pilot(o.after)

      if new do
        assert {:grant, new} in o.actions, inspect(o)
        assert o.after.epoch == o.before.epoch + 1, inspect(o)
      end

      if old = Policy.pilot(o.before) do
        stop = Enum.find_index(o.actions, &match?({:stop, _}, &1))
        assert stop != nil, "pilot changed without a stop: #{inspect(o)}"
        assert {:revoke, old, elem(Enum.at(o.actions, stop), 1)} in o.actions

        if grant = Enum.find_index(o.actions, &match?({:grant, _}, &1)),
          do: assert(stop < grant, inspect(o))
      end
    end
  end

  test "observers never pilot and only the pilot's commands run" do
    for o <- all_outcomes() do
      refute match?(%{role: :observer}, Policy.pilot(o.after)), inspect(o)

      if :run in o.actions do
        assert Policy.pilot(o.before).id == p(o.sender).id, inspect(o)
        assert o.reply == :ok
      end
    end
  end

  test "every change of the helm is broadcast; nothing else is" do
    for o <- all_outcomes() do
      changed? = o.after.helm != o.before.helm or o.after.epoch != o.before.epoch
      assert changed? == :changed in o.actions, inspect(o)
    end
  end

  test "the pilot's own messages (only) refresh the deadman" do
    for o <- all_outcomes(), o.state != :free, is_tuple(o.ev), not match?({:tick, _}, o.ev) do
      from_pilot? = pilot_key(o.state) == o.sender and is_map(elem(o.ev, 1))
      still_piloting? = Policy.pilot(o.after) == Policy.pilot(o.before)

      if still_piloting? do
        expected = if from_pilot?, do: o.now, else: @t0
        assert o.after.last_seen_ms == expected, inspect(o)
      end
    end
  end

  describe "deadman" do
    test "trips once, keeps the pilot; only a fresh command re-arms it" do
      {{:ok, :granted}, s, _} = Policy.handle(Policy.new(), {:request, p(:a)}, 0)
      assert s.epoch == 1
      {:ok, s, []} = Policy.handle(s, {:tick, 500}, 500)
      {:ok, s, [{:stop, "deadman"}, :changed]} = Policy.handle(s, {:tick, 500}, 501)
      assert s.epoch == 2 and s.tripped and Policy.pilot(s) == p(:a)
      # silent on: no second stop
      {:ok, s, []} = Policy.handle(s, {:tick, 500}, 5_000)
      # a helper's heartbeat does not count (ArduSub #17724)
      {{:error, "not_in_control"}, s, []} = Policy.handle(s, {:heartbeat, p(:b)}, 5_001)
      assert s.tripped
      # the pilot's heartbeats come back, then stop again: no second stop
      {:ok, s, []} = Policy.handle(s, {:heartbeat, p(:a)}, 5_001)
      assert s.tripped
      {:ok, s, []} = Policy.handle(s, {:tick, 500}, 6_000)
      # a command stamped before the client heard of the trip is stale and re-arms nothing
      {{:error, "stale_command"}, s, []} = Policy.handle(s, {:command, p(:a), {:epoch, 1}}, 6_002)
      assert s.tripped
      # a fresh command runs and re-arms the deadman
      {:ok, s, [:run]} = Policy.handle(s, {:command, p(:a), {:epoch, 2}}, 6_003)
      refute s.tripped
      {:ok, _s, [{:stop, "deadman"}, :changed]} = Policy.handle(s, {:tick, 500}, 6_504)
    end

    test "another connection of the pilot's own user does not feed the deadman" do
      a2 = %{p(:a) | id: "a2"}
      {_, s, _} = Policy.handle(Policy.new(), {:request, p(:a)}, 0)
      {{:error, "not_in_control"}, s, []} = Policy.handle(s, {:heartbeat, a2}, 400)
      assert {:ok, _, [{:stop, "deadman"}, :changed]} = Policy.handle(s, {:tick, 500}, 600)
    end
  end

  test "a full handover: request, accept, the old epoch is stale for both" do
    {_, s, _} = Policy.handle(Policy.new(), {:request, p(:a)}, 0)
    {{:ok, :pending}, s, _} = Policy.handle(s, {:request, p(:b)}, 1)
    {:ok, s, actions} = Policy.handle(s, {:answer, p(:a), true}, 2)

    assert [{:stop, "control_transferred"}, {:revoke, _, _}, {:grant, %{id: "b"}}, :changed] =
             actions

    assert {{:error, "not_in_control"}, _, []} =
             Policy.handle(s, {:command, p(:a), {:epoch, s.epoch}}, 3)

    assert {{:error, "stale_command"}, _, []} =
             Policy.handle(s, {:command, p(:b), {:epoch, s.epoch - 1}}, 3)

    assert {:ok, _, [:run]} = Policy.handle(s, {:command, p(:b), {:epoch, s.epoch}}, 3)
  end

  test "helpers" do
    s = policy({:requested, :a, :b})
    assert Policy.pilot(s) == p(:a)
    assert Policy.parties(s) == [p(:a), p(:b)]
    assert Policy.name(s) == :requested
    assert Policy.name(Policy.new()) == :free
    assert Policy.parties(Policy.new()) == []
    assert Policy.pilot(Policy.new()) == nil
  end
end
