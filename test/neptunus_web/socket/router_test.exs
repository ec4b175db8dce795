defmodule NeptunusWeb.Socket.RouterTest do
  # The Channels protocol's server side without sockets: frames in, frames and effects out.
  use ExUnit.Case, async: true

  alias NeptunusWeb.Channel
  alias NeptunusWeb.Channels.Wire
  alias NeptunusWeb.Channels.Wire.Message
  alias NeptunusWeb.Socket.Router

  defmodule FakeChannel do
    @moduledoc false
    # A channel whose behaviour the client's payloads choose; every callback reports to the
    # connection's process (the test).
    @behaviour NeptunusWeb.Channel

    @impl true
    def join(topic, payload, socket) do
      send(socket.transport_pid, {:join, topic, payload, socket})

      case payload do
        %{"refuse" => reason} -> {:error, %{reason: reason}}
        %{"raise" => true} -> raise "join failed on purpose"
        %{"reply" => "unencodable"} -> {:ok, %{bad: {:tuple}}, socket}
        %{"reply" => "not a map"} -> {:error, :nope}
        _ -> {:ok, %{joined: topic}, Channel.assign(socket, calls: 0)}
      end
    end

    @impl true
    def handle_in(event, payload, socket) do
      send(socket.transport_pid, {:handle_in, event, payload, socket})
      socket = Channel.assign(socket, calls: socket.assigns.calls + 1)

      case event do
        "echo" -> {:reply, {:ok, payload}, socket}
        "refuse" -> {:reply, {:error, %{reason: "refused"}}, socket}
        "calls" -> {:reply, {:ok, %{calls: socket.assigns.calls}}, socket}
        "bad_status" -> {:reply, {:maybe, %{}}, socket}
        "raise" -> raise "handle_in failed on purpose"
      end
    end

    @impl true
    def handle_info(msg, socket) do
      send(socket.transport_pid, {:handle_info, msg, socket})

      case msg do
        {:push, event, payload} -> {:push, event, payload, socket}
        :count -> {:noreply, Channel.assign(socket, calls: socket.assigns.calls + 1)}
        :throw -> throw(:on_purpose)
      end
    end

    @impl true
    def terminate(_reason, _socket), do: raise("the router must not call terminate/2 itself")
  end

  defmodule OtherChannel do
    @moduledoc false
    @behaviour NeptunusWeb.Channel

    @impl true
    def join(topic, payload, socket) do
      send(socket.transport_pid, {:join, topic, payload, socket})
      {:ok, %{other: topic}, socket}
    end

    @impl true
    def handle_in(_event, _payload, socket), do: {:reply, {:ok, %{other: true}}, socket}
    @impl true
    def handle_info(_msg, socket), do: {:noreply, socket}
    @impl true
    def terminate(_reason, _socket), do: :ok
  end

  @user %{id: "conn-1", name: "Ada", role: :pilot}
  @routes [{"lobby", OtherChannel}, {"room:*", FakeChannel}, {"room:other", OtherChannel}]

  setup do
    {:ok, router: Router.new(@user, self(), @routes)}
  end

  defp frame(join_ref, ref, topic, event, payload),
    do: {:text, Wire.encode(join_ref, ref, topic, event, payload)}

  defp decode!(frame), do: :jiffy.decode(frame, [:return_maps, {:null_term, nil}])

  defp handle(router, message) do
    {router, frames, effects} = Router.handle_message(router, message)
    {router, Enum.map(frames, &decode!/1), effects}
  end

  # Runs a join as the shell would: watched and subscribed with `:ok`.
  defp join!(router, topic, join_ref, payload \\ %{}) do
    ref = "#{join_ref}-join"

    {router, [], [{:watch, %Message{topic: ^topic} = msg}]} =
      handle(router, frame(join_ref, ref, topic, "phx_join", payload))

    {router, [], [{:subscribe, ^msg, reply}]} = handle(router, {:watched, msg, :ok})
    assert_received {:join, ^topic, ^payload, %Channel.Socket{join_ref: ^join_ref}}
    {router, [^reply], [:gc]} = Router.handle_message(router, {:subscribed, msg, reply, :ok})

    assert [^join_ref, ^ref, ^topic, "phx_reply", %{"status" => "ok", "response" => response}] =
             decode!(reply)

    {router, response}
  end

  defp leave_effects(topic, reason) do
    [
      {:unsubscribe, topic},
      {:terminate, FakeChannel, reason, :socket},
      {:untrack, topic}
    ]
  end

  # the effects of leaving `topic`, with the channel's socket replaced for comparison
  defp normalized(effects) do
    Enum.map(effects, fn
      {:terminate, module, reason, %Channel.Socket{topic: topic}} ->
        {:terminate, module, reason, if(topic == nil, do: :no_topic, else: :socket)}

      {:log, level, text} ->
        {:log, level, String.slice(text, 0, 20)}

      other ->
        other
    end)
  end

  test "a heartbeat is answered ok with its ref", %{router: router} do
    assert {^router,
            [[nil, "hb1", "phoenix", "phx_reply", %{"status" => "ok", "response" => %{}}]],
            []} = handle(router, frame(nil, "hb1", "phoenix", "heartbeat", %{}))
  end

  describe "join" do
    test "watch, the channel's join, subscribe, then the ok reply", %{router: router} do
      {router, response} = join!(router, "room:1", "1", %{"x" => 1})
      assert response == %{"joined" => "room:1"}
      assert Router.joined?(router, "room:1")
      assert Router.topics(router) == ["room:1"]
    end

    test "the channel's socket carries topic, join ref, user and connection process",
         %{router: router} do
      {router, [], [{:watch, msg}]} = handle(router, frame("7", "8", "room:1", "phx_join", %{}))
      handle(router, {:watched, msg, :ok})
      assert_received {:join, "room:1", %{}, socket}
      assert %Channel.Socket{topic: "room:1", join_ref: "7", user: @user} = socket
      assert socket.transport_pid == self()
    end

    test "the channel joins only once the services are watched", %{router: router} do
      {_, [], [{:watch, _}]} = handle(router, frame("1", "2", "room:1", "phx_join", %{}))
      refute_received {:join, _, _, _}
    end

    test "a topic no route matches is unmatched, with nothing to do", %{router: router} do
      for topic <- ["room", "roomy:1", "lobby:1", "phoenix"] do
        assert {^router, [["1", "2", ^topic, "phx_reply", reply]], []} =
                 handle(router, frame("1", "2", topic, "phx_join", %{}))

        assert reply == %{"status" => "error", "response" => %{"reason" => "unmatched topic"}}
      end
    end

    test "routes: exact or prefix patterns, the first match wins", %{router: router} do
      {router, response} = join!(router, "lobby", "1")
      assert response == %{"other" => "lobby"}
      # "room:*" comes before "room:other"
      {_, response} = join!(router, "room:other", "2")
      assert response == %{"joined" => "room:other"}
      assert Router.route(@routes, "room:") == FakeChannel
      assert Router.route(@routes, "lobby2") == nil
    end

    test "while the services restart, the join is refused and the channel never joins",
         %{router: router} do
      {router, [], [{:watch, msg}]} = handle(router, frame("1", "2", "room:1", "phx_join", %{}))

      assert {^router, [["1", "2", "room:1", "phx_reply", reply]], []} =
               handle(router, {:watched, msg, :restarting})

      assert reply == %{
               "status" => "error",
               "response" => %{"reason" => "server restarting: join again"}
             }

      refute_received {:join, _, _, _}
      refute Router.joined?(router, "room:1")
    end

    test "a subscription that fails leaves the joined channel and refuses the join",
         %{router: router} do
      {router, [], [{:watch, msg}]} = handle(router, frame("1", "2", "room:1", "phx_join", %{}))
      {router, [], [{:subscribe, ^msg, reply}]} = handle(router, {:watched, msg, :ok})

      {router, [frame], effects} = handle(router, {:subscribed, msg, reply, :restarting})
      assert ["1", "2", "room:1", "phx_reply", %{"status" => "error", "response" => r}] = frame
      assert r == %{"reason" => "server restarting: join again"}
      assert normalized(effects) == leave_effects("room:1", {:shutdown, :left})
      refute Router.joined?(router, "room:1")
    end

    test "a refused join is answered with the channel's reason and not joined",
         %{router: router} do
      {router, [], [{:watch, msg}]} =
        handle(router, frame("1", "2", "room:1", "phx_join", %{"refuse" => "no such room"}))

      assert {^router, [["1", "2", "room:1", "phx_reply", reply]], []} =
               handle(router, {:watched, msg, :ok})

      assert reply == %{"status" => "error", "response" => %{"reason" => "no such room"}}
      refute Router.joined?(router, "room:1")
    end

    test "a join that raises, returns a bad value or an unencodable reply: join crashed",
         %{router: router} do
      for {payload, left?} <- [
            {%{"raise" => true}, false},
            {%{"reply" => "not a map"}, false},
            {%{"reply" => "unencodable"}, true}
          ] do
        {^router, [], [{:watch, msg}]} =
          handle(router, frame("1", "2", "room:1", "phx_join", payload))

        assert {^router, [["1", "2", "room:1", "phx_reply", reply]], effects} =
                 handle(router, {:watched, msg, :ok})

        assert reply == %{"status" => "error", "response" => %{"reason" => "join crashed"}}
        assert [{:log, :error, "join room:1 failed: " <> _} | leave] = effects
        # a channel that did join is left again
        assert normalized(leave) ==
                 if(left?, do: leave_effects("room:1", {:error, :crashed}), else: [])
      end
    end

    test "a rejoin leaves the old channel first; its join ref goes stale", %{router: router} do
      {router, _} = join!(router, "room:1", "1")

      {router, [], effects} = handle(router, frame("2", "2-join", "room:1", "phx_join", %{}))

      assert [
               {:unsubscribe, "room:1"},
               {:terminate, FakeChannel, reason, old},
               {:untrack, "room:1"},
               {:watch, msg}
             ] = effects

      assert reason == {:shutdown, :rejoin} and old.join_ref == "1"
      refute Router.joined?(router, "room:1")

      {router, [], [{:subscribe, ^msg, reply}]} = handle(router, {:watched, msg, :ok})
      {router, _, [:gc]} = handle(router, {:subscribed, msg, reply, :ok})

      assert {_, [["1", "3", "room:1", "phx_reply", %{"response" => %{"reason" => r}}]], []} =
               handle(router, frame("1", "3", "room:1", "echo", %{}))

      assert r == "unmatched topic"

      assert {_, [["2", "4", "room:1", "phx_reply", %{"status" => "ok"}]], []} =
               handle(router, frame("2", "4", "room:1", "echo", %{}))
    end

    test "a rejoin of a topic no route matches any more still leaves the old channel" do
      router = Router.new(@user, self(), [{"room:*", FakeChannel}])
      {router, _} = join!(router, "room:1", "1")
      router = %{router | routes: []}

      assert {router, [[_, _, _, _, %{"response" => %{"reason" => "unmatched topic"}}]], effects} =
               handle(router, frame("2", "2", "room:1", "phx_join", %{}))

      assert normalized(effects) == leave_effects("room:1", {:shutdown, :rejoin})
      refute Router.joined?(router, "room:1")
    end
  end

  describe "leave" do
    test "ok, then phx_close with the join ref; the channel is left", %{router: router} do
      {router, _} = join!(router, "room:1", "1")
      {router, frames, effects} = handle(router, frame("1", "5", "room:1", "phx_leave", %{}))

      assert frames == [
               ["1", "5", "room:1", "phx_reply", %{"status" => "ok", "response" => %{}}],
               ["1", "1", "room:1", "phx_close", %{}]
             ]

      assert normalized(effects) == leave_effects("room:1", {:shutdown, :left})
      refute Router.joined?(router, "room:1")

      assert {^router, [[_, _, _, _, %{"response" => %{"reason" => "unmatched topic"}}]], []} =
               handle(router, frame("1", "6", "room:1", "echo", %{}))
    end

    test "leaving a topic not joined, or with a stale join ref, is unmatched",
         %{router: router} do
      assert {^router, [[_, _, _, _, %{"response" => %{"reason" => "unmatched topic"}}]], []} =
               handle(router, frame("1", "5", "room:1", "phx_leave", %{}))

      {router, _} = join!(router, "room:1", "1")

      assert {^router, [[_, _, _, _, %{"response" => %{"reason" => "unmatched topic"}}]], []} =
               handle(router, frame("9", "5", "room:1", "phx_leave", %{}))
    end
  end

  describe "pushes" do
    test "a push to a joined topic gets the channel's reply, addressed to it",
         %{router: router} do
      {router, _} = join!(router, "room:1", "1")

      assert {_, [["1", "8", "room:1", "phx_reply", reply]], []} =
               handle(router, frame("1", "8", "room:1", "echo", %{"a" => [1, nil]}))

      assert reply == %{"status" => "ok", "response" => %{"a" => [1, nil]}}
      assert_received {:handle_in, "echo", %{"a" => [1, nil]}, %Channel.Socket{join_ref: "1"}}

      assert {_, [["1", "9", "room:1", "phx_reply", %{"status" => "error"} = error]], []} =
               handle(router, frame("1", "9", "room:1", "refuse", %{}))

      assert error["response"] == %{"reason" => "refused"}
    end

    test "the channel's socket is kept between callbacks", %{router: router} do
      {router, _} = join!(router, "room:1", "1")
      {router, _, []} = handle(router, frame("1", "a", "room:1", "echo", %{}))
      {router, [], []} = handle(router, {:channel_info, "room:1", :count})

      assert {_, [[_, _, _, _, %{"response" => %{"calls" => 3}}]], []} =
               handle(router, frame("1", "b", "room:1", "calls", %{}))
    end

    test "a push without a join ref reaches the joined channel", %{router: router} do
      {router, _} = join!(router, "room:1", "1")

      assert {_, [[nil, "8", "room:1", "phx_reply", %{"status" => "ok"}]], []} =
               handle(router, frame(nil, "8", "room:1", "echo", %{}))
    end

    test "a push to a topic not joined, or with a stale join ref, is unmatched",
         %{router: router} do
      assert {^router, [["9", "1", "room:1", "phx_reply", reply]], []} =
               handle(router, frame("9", "1", "room:1", "echo", %{}))

      assert reply == %{"status" => "error", "response" => %{"reason" => "unmatched topic"}}

      {router, _} = join!(router, "room:1", "1")

      assert {^router, [["9", "2", "room:1", "phx_reply", %{"status" => "error"}]], []} =
               handle(router, frame("9", "2", "room:1", "echo", %{}))

      refute_received {:handle_in, _, _, _}
    end

    test "a channel that raises gets phx_error and is left; the other channels stay",
         %{router: router} do
      {router, _} = join!(router, "room:2", "2")

      for event <- ["raise", "bad_status"] do
        {router, _} = join!(router, "room:1", "1")
        {router, frames, effects} = handle(router, frame("1", "3", "room:1", event, %{}))
        assert frames == [["1", "1", "room:1", "phx_error", %{}]]
        assert [{:log, :error, "channel room:1 crashed: " <> _} | leave] = effects
        assert normalized(leave) == leave_effects("room:1", {:error, :crashed})
        refute Router.joined?(router, "room:1")

        assert {_, [["2", "4", "room:2", "phx_reply", %{"status" => "ok"}]], []} =
                 handle(router, frame("2", "4", "room:2", "echo", %{}))
      end
    end
  end

  describe "channel messages" do
    test "a push from the channel goes to the client with its join ref", %{router: router} do
      {router, _} = join!(router, "room:1", "1")

      assert {_, [["1", nil, "room:1", "news", %{"n" => 1}]], []} =
               handle(router, {:channel_info, "room:1", {:push, "news", %{n: 1}}})
    end

    test "a message for a topic not joined is dropped", %{router: router} do
      assert {^router, [], []} = handle(router, {:channel_info, "room:1", {:push, "x", %{}}})
      refute_received {:handle_info, _, _}
    end

    test "a channel that throws gets phx_error and is left", %{router: router} do
      {router, _} = join!(router, "room:1", "1")
      {router, frames, effects} = handle(router, {:channel_info, "room:1", :throw})
      assert frames == [["1", "1", "room:1", "phx_error", %{}]]
      assert [{:log, :error, _} | leave] = effects
      assert normalized(leave) == leave_effects("room:1", {:error, :crashed})
      refute Router.joined?(router, "room:1")
    end

    test "a push the channel cannot encode is a crash too", %{router: router} do
      {router, _} = join!(router, "room:1", "1")

      assert {_, [["1", "1", "room:1", "phx_error", %{}]], [{:log, :error, _} | _]} =
               handle(router, {:channel_info, "room:1", {:push, "bad", %{pid: self()}}})
    end
  end

  describe "malformed frames" do
    test "are answered with a readable reason, addressed as far as the frame allows",
         %{router: router} do
      assert {^router, [[nil, nil, "phoenix", "phx_reply", %{"response" => %{"reason" => r}}]],
              []} = handle(router, {:text, "{not json"})

      assert r =~ "invalid JSON"

      assert {^router, [["1", "2", "room:1", "phx_reply", %{"status" => "error"} = reply]], []} =
               handle(router, {:text, ~s(["1","2","room:1","echo","fast"])})

      assert reply["response"] == %{"reason" => "payload must be a JSON object"}

      assert {^router, [[nil, nil, "phoenix", "phx_reply", %{"status" => "error"}]], []} =
               handle(router, {:text, "[1,2,3]"})

      assert {^router, [[nil, nil, "phoenix", "phx_reply", %{"response" => %{"reason" => r}}]],
              []} = handle(router, {:binary, <<1, 2, 3>>})

      assert r =~ "binary frames are not supported"
    end

    test "any text gets at most one reply and changes nothing unless it is a valid frame",
         %{router: router} do
      {router, _} = join!(router, "room:1", "1")

      text =
        :proper_types.oneof([
          :proper_types.binary(),
          Neptunus.Test.Properties.bind(
            :proper_types.list(
              :proper_types.oneof([
                :proper_types.elements([nil, "1", "phoenix", "room:1", "heartbeat", "echo"]),
                :proper_types.integer()
              ])
            ),
            &Neptunus.JSON.encode!/1
          )
        ])

      Neptunus.Test.Properties.check(text, fn text ->
        {after_, frames, effects} = Router.handle_message(router, {:text, text})

        valid? = match?({:ok, _}, Wire.decode(text))

        length(frames) <= 1 and Enum.all?(frames, &match?([_, _, _, _, _], decode!(&1))) and
          (valid? or (after_ == router and effects == [] and length(frames) == 1))
      end)
    end
  end

  test "a closing connection leaves every channel", %{router: router} do
    {router, _} = join!(router, "room:1", "1")
    {router, _} = join!(router, "room:2", "2")
    {router, [], effects} = handle(router, {:closed, :normal})

    assert Enum.sort(normalized(effects)) ==
             Enum.sort(
               leave_effects("room:1", {:shutdown, :normal}) ++
                 leave_effects("room:2", {:shutdown, :normal})
             )

    assert Router.topics(router) == []
  end

  test "a malformed route is refused" do
    for bad <- [[{"", FakeChannel}], [{:room, FakeChannel}], [{"room", "Fake"}], [:room]] do
      assert_raise ArgumentError, ~r/a route is/, fn -> Router.new(@user, self(), bad) end
    end
  end
end
