defmodule Neptunus.Fleet.ClusterConfigTest do
  use ExUnit.Case, async: true

  alias Neptunus.Config.Cluster
  alias Neptunus.Test.Properties

  doctest Neptunus.Config.Cluster

  @cookie String.duplicate("s3cr3t-", 6)

  defp env(overrides), do: Map.merge(%{"NEPTUNUS_COOKIE" => @cookie}, overrides)

  defp pem_files!(ctx) do
    dir = Path.join(System.tmp_dir!(), "cluster-config-#{System.unique_integer([:positive])}")
    File.mkdir_p!(dir)
    on_exit(fn -> File.rm_rf!(dir) end)

    for name <- ~w(cert key ca), into: %{} do
      path = Path.join(dir, "#{name}.pem")
      File.write!(path, "pem")
      {name, path}
    end
    |> then(&Map.put(ctx, :pem, &1))
  end

  defp tls_env(%{"cert" => cert, "key" => key, "ca" => ca}) do
    %{"NEPTUNUS_DIST_CERT" => cert, "NEPTUNUS_DIST_KEY" => key, "NEPTUNUS_DIST_CACERT" => ca}
  end

  test "NEPTUNUS_VEHICLES=none: a node without vehicles (topside, relay)" do
    assert Neptunus.Config.Vehicles.vehicles!(%{"NEPTUNUS_VEHICLES" => " none "}) == []
  end

  test "no NEPTUNUS_NODE: a single node, nothing distributed" do
    assert Cluster.cluster!(%{}) == nil
    assert Cluster.cluster!(%{"NEPTUNUS_NODE" => "  "}) == nil
  end

  test "cluster settings without NEPTUNUS_NODE are refused, naming the variable" do
    for variable <- ~w(NEPTUNUS_COOKIE NEPTUNUS_CLUSTER NEPTUNUS_DIST_CERT) do
      e = assert_raise ArgumentError, fn -> Cluster.cluster!(%{variable => "x@y"}) end
      assert e.message =~ "#{variable} is set but NEPTUNUS_NODE is not"
    end
  end

  test "a loopback node: long or short names, plain TCP, the cluster without itself" do
    c =
      Cluster.cluster!(
        env(%{
          "NEPTUNUS_NODE" => "rov1@127.0.0.1",
          "NEPTUNUS_CLUSTER" => "top@127.0.0.1, rov1@127.0.0.1,top@127.0.0.1 ,rov2@127.0.0.1"
        })
      )

    assert c == %{
             node: :"rov1@127.0.0.1",
             names: :longnames,
             cookie: String.to_atom(@cookie),
             cluster: [:"top@127.0.0.1", :"rov2@127.0.0.1"],
             loopback: true,
             tls: nil
           }

    assert %{names: :shortnames, loopback: true, cluster: []} =
             Cluster.cluster!(env(%{"NEPTUNUS_NODE" => "rov1@localhost"}))

    assert %{names: :longnames, loopback: true} =
             Cluster.cluster!(env(%{"NEPTUNUS_NODE" => "rov1@::1"}))
  end

  test "bad node names are refused with an example" do
    for bad <- ["rov1", "rov 1@127.0.0.1", "@127.0.0.1", "rov1@", "a@b@c", "rov1@host/x"] do
      e = assert_raise ArgumentError, fn -> Cluster.cluster!(env(%{"NEPTUNUS_NODE" => bad})) end
      assert e.message =~ "NEPTUNUS_NODE=#{inspect(bad)} is not valid: expected a node name"
    end

    for bad <- ["top", "top@127.0.0.1,,x@y", "top@127.0.0.1, bad name@x"] do
      e =
        assert_raise ArgumentError, fn ->
          Cluster.cluster!(env(%{"NEPTUNUS_NODE" => "rov1@127.0.0.1", "NEPTUNUS_CLUSTER" => bad}))
        end

      assert e.message =~ "NEPTUNUS_CLUSTER="
    end
  end

  test "the cookie is required, at least 32 printable characters, and never in a message" do
    e =
      assert_raise ArgumentError, fn ->
        Cluster.cluster!(%{"NEPTUNUS_NODE" => "rov1@127.0.0.1"})
      end

    assert e.message =~ "NEPTUNUS_COOKIE is not set"

    short = "short-secret-cookie-31-character"
    assert String.length(short) == 32
    short = String.slice(short, 0, 31)

    e =
      assert_raise ArgumentError, fn ->
        Cluster.cluster!(%{"NEPTUNUS_NODE" => "rov1@127.0.0.1", "NEPTUNUS_COOKIE" => short})
      end

    assert e.message =~ "NEPTUNUS_COOKIE is too short: expected at least 32"
    refute e.message =~ short

    spaced = "a secret cookie with spaces in it, long enough"

    e =
      assert_raise ArgumentError, fn ->
        Cluster.cluster!(%{"NEPTUNUS_NODE" => "rov1@127.0.0.1", "NEPTUNUS_COOKIE" => spaced})
      end

    assert e.message =~ "printable ASCII"
    refute e.message =~ "secret cookie"
  end

  test "off loopback without TLS files: refuses, saying what to set" do
    for name <- ["rov1@10.0.0.2", "rov1@beaglebone", "rov1@rov1.example.org"] do
      e = assert_raise ArgumentError, fn -> Cluster.cluster!(env(%{"NEPTUNUS_NODE" => name})) end
      assert e.message =~ "is not on loopback"
      assert e.message =~ "NEPTUNUS_DIST_CERT, NEPTUNUS_DIST_KEY and NEPTUNUS_DIST_CACERT"
      refute e.message =~ @cookie
    end
  end

  test "off loopback with the TLS files: TLS distribution", ctx do
    %{pem: pem} = pem_files!(ctx)
    c = Cluster.cluster!(env(Map.put(tls_env(pem), "NEPTUNUS_NODE", "rov1@10.0.0.2")))

    assert c.tls == %{certfile: pem["cert"], keyfile: pem["key"], cacertfile: pem["ca"]}
    assert c.loopback == false

    optfile = Cluster.ssl_dist_optfile(c.tls)
    {:ok, tokens, _} = :erl_scan.string(String.to_charlist(optfile))
    {:ok, [server: server, client: client]} = :erl_parse.parse_term(tokens)
    assert server[:verify] == :verify_peer and server[:fail_if_no_peer_cert] == true
    assert client[:certfile] == String.to_charlist(pem["cert"])
    assert client[:cacertfile] == String.to_charlist(pem["ca"])
  end

  test "TLS files: all three, and they must exist", ctx do
    %{pem: pem} = pem_files!(ctx)
    base = env(Map.put(tls_env(pem), "NEPTUNUS_NODE", "rov1@10.0.0.2"))

    e =
      assert_raise ArgumentError, fn ->
        Cluster.cluster!(Map.delete(base, "NEPTUNUS_DIST_KEY"))
      end

    assert e.message =~ "NEPTUNUS_DIST_KEY=\"\" is not valid"

    e =
      assert_raise ArgumentError, fn ->
        Cluster.cluster!(Map.put(base, "NEPTUNUS_DIST_CACERT", "/nonexistent/ca.pem"))
      end

    assert e.message =~ "NEPTUNUS_DIST_CACERT=\"/nonexistent/ca.pem\" is not valid"
  end

  test "TLS needs the VM started with -proto_dist inet_tls", ctx do
    %{pem: pem} = pem_files!(ctx)
    c = Cluster.cluster!(env(Map.put(tls_env(pem), "NEPTUNUS_NODE", "rov1@10.0.0.2")))

    assert Cluster.check_proto_dist(c, {:ok, [[~c"inet_tls"]]}) == :ok
    assert {:error, message} = Cluster.check_proto_dist(c, :error)
    assert message =~ "-proto_dist inet_tls -ssl_dist_optfile"
    assert {:error, _} = Cluster.check_proto_dist(c, {:ok, [[~c"inet_tcp"]]})
    assert Cluster.check_proto_dist(%{c | tls: nil}, :error) == :ok
  end

  describe "property" do
    # text from an alphabet that makes node names, lists and near misses
    defp text do
      chars = Enum.map(~c"ab1@.,: -_x", &:proper_types.exactly/1)
      :proper_types.list(:proper_types.oneof(chars)) |> Properties.bind(&List.to_string/1)
    end

    test "any environment: settings or a clear error that never shows the cookie" do
      cookie_gen =
        :proper_types.oneof([
          :proper_types.exactly(nil),
          Properties.bind(:proper_types.integer(20, 40), &("C" <> String.duplicate("k", &1)))
        ])

      generator =
        :proper_types.tuple([
          :proper_types.oneof([:proper_types.exactly(nil), text()]),
          cookie_gen,
          :proper_types.oneof([:proper_types.exactly(nil), text()])
        ])

      Properties.check(generator, fn {name, cookie, cluster} ->
        env =
          [{"NEPTUNUS_NODE", name}, {"NEPTUNUS_COOKIE", cookie}, {"NEPTUNUS_CLUSTER", cluster}]
          |> Enum.reject(&(elem(&1, 1) == nil))
          |> Map.new()

        try do
          case Cluster.cluster!(env) do
            nil ->
              String.trim(name || "") == ""

            %{node: node, cluster: nodes, cookie: c} ->
              Atom.to_string(c) == cookie and node not in nodes and
                Enum.all?(nodes, &(&1 |> Atom.to_string() |> String.contains?("@")))
          end
        rescue
          e in ArgumentError -> cookie == nil or not String.contains?(e.message, cookie)
        end
      end)
    end
  end
end
