defmodule Neptunus.Settings.RulesTest do
  use ExUnit.Case, async: true

  alias Neptunus.Settings.Rules
  alias Neptunus.Test.Properties

  doctest Neptunus.Settings.Rules
  doctest Neptunus.Config.Settings

  describe "NEPTUNUS_SETTINGS" do
    @tag :tmp_dir
    test "a directory (existing or not), never a file or empty", %{tmp_dir: dir} do
      alias Neptunus.Config.Settings, as: C
      assert C.settings_dir!(%{"NEPTUNUS_SETTINGS" => dir}, "settings") == dir
      assert C.settings_dir!(%{"NEPTUNUS_SETTINGS" => dir <> "/new"}, "settings") == dir <> "/new"
      file = Path.join(dir, "f")
      File.write!(file, "")

      assert_raise ArgumentError, ~r/NEPTUNUS_SETTINGS=.*a directory \(this is a file\)/, fn ->
        C.settings_dir!(%{"NEPTUNUS_SETTINGS" => file}, "settings")
      end

      assert_raise ArgumentError, ~r/NEPTUNUS_SETTINGS="" is not valid/, fn ->
        C.settings_dir!(%{"NEPTUNUS_SETTINGS" => " "}, "settings")
      end
    end
  end

  describe "scope/1" do
    test "users and vehicles with sensible names" do
      assert Rules.scope({:user, "alice"}) == :ok
      assert Rules.scope({:vehicle, "neptunus-1"}) == :ok
      assert Rules.scope({:user, "Ålesund ø"}) == :ok
      assert Rules.scope({:user, String.duplicate("a", 64)}) == :ok
    end

    test "refuses empty, long, non-UTF-8, control characters and other shapes" do
      for bad <- ["", String.duplicate("a", 65), <<0xFF>>, "a\nb", "a\0", 42, nil] do
        assert {:error, reason} = Rules.scope({:user, bad}), inspect(bad)
        assert reason =~ "user name must be"
        assert {:error, reason} = Rules.scope({:vehicle, bad})
        assert reason =~ "vehicle id must be"
      end

      assert {:error, "a scope must be" <> _} = Rules.scope({:user, "a", "b"})
      assert {:error, "a scope must be" <> _} = Rules.scope("alice")
    end
  end

  describe "key/1" do
    test "letters, digits, dot, underscore and dash, 1..64" do
      assert Rules.key("gamepad.mapping") == :ok
      assert Rules.key("developer_plots-2") == :ok
      assert Rules.key(String.duplicate("k", 64)) == :ok

      for bad <- ["", String.duplicate("k", 65), "a/b", "a b", ".", "..", "é", 1, nil, :atom] do
        assert {:error, "a key must be" <> _} = Rules.key(bad), inspect(bad)
      end
    end
  end

  describe "value/1" do
    test "JSON values" do
      for good <- [nil, true, 1, -2.5, "x", [], %{}, [1, [2, %{"a" => nil}]]] do
        assert Rules.value(good) == :ok, inspect(good)
      end
    end

    test "refuses what JSON cannot say, naming it" do
      assert {:error, reason} = Rules.value({1, 2})
      assert reason =~ "{1, 2} is not JSON"
      assert {:error, reason} = Rules.value(%{1 => 2})
      assert reason =~ "1 is not a string key"
      assert {:error, reason} = Rules.value([self()])
      assert reason =~ "is not JSON"
      assert {:error, reason} = Rules.value(:atom)
      assert reason =~ ":atom is not JSON"
      assert {:error, reason} = Rules.value(<<0xFF>>)
      assert reason =~ "not UTF-8"
      assert {:error, reason} = Rules.value([1 | 2])
      assert reason =~ "improper list"
      assert {:error, _} = Rules.value(%{"a" => [%{"b" => {:deep}}]})
      assert {:error, _} = Rules.value(~D[2026-01-01])
    end

    test "at most max_value_bytes of JSON" do
      # a string's JSON is its text and two quotes
      fits = String.duplicate("x", Rules.max_value_bytes() - 2)
      assert Rules.value(fits) == :ok
      assert {:error, reason} = Rules.value(fits <> "x")
      assert reason == "a value must be at most 16384 bytes of JSON, got 16385"
    end
  end

  describe "put/3" do
    test "adds and replaces; bad keys and values change nothing" do
      assert {:ok, %{"a" => 1}} = Rules.put(%{}, "a", 1)
      assert {:ok, %{"a" => 2}} = Rules.put(%{"a" => 1}, "a", 2)
      assert {:error, "a key must be" <> _} = Rules.put(%{}, "a/b", 1)
      assert {:error, "a value must be" <> _} = Rules.put(%{}, "a", {1})
    end

    test "at most max_keys keys; replacing one of them still works" do
      full = Map.new(1..Rules.max_keys(), &{"k#{&1}", &1})
      assert {:error, "a scope holds at most 64 settings" <> _} = Rules.put(full, "new", 1)
      assert {:ok, %{"k1" => "again"}} = Rules.put(full, "k1", "again")
    end
  end

  describe "files" do
    test "path encodes the name: nothing reaches outside the directory" do
      assert Rules.path("d", {:user, "../../etc/passwd"}) ==
               "d/user/Li4vLi4vZXRjL3Bhc3N3ZA.json"

      refute Rules.path("d", {:user, "Alice"}) == Rules.path("d", {:user, "alice"})
    end

    test "a file is all or nothing" do
      scope = {:user, "a"}

      assert {:error, "invalid JSON" <> _} = Rules.decode_file("{", scope)
      assert {:error, "the file is not of user" <> _} = Rules.decode_file("[]", scope)

      assert {:error, "the file is not of user" <> _} =
               Rules.decode_file(~s({"user":"a","settings":{},"x":1}), scope)

      assert {:error, "the file is not of user" <> _} =
               Rules.decode_file(~s({"vehicle":"a","settings":{}}), scope)

      assert {:error, "setting \"a/b\": a key must be" <> _} =
               Rules.decode_file(~s({"user":"a","settings":{"ok":1,"a/b":2}}), scope)

      big = Map.new(1..65, &{"k#{&1}", 1})

      assert {:error, "the file holds 65 settings, more than 64"} =
               Rules.decode_file(Rules.encode_file(scope, big), scope)
    end

    test "property: what put accepts, the file gives back" do
      entry =
        :proper_types.tuple([
          :proper_types.oneof([:proper_types.exactly("a"), :proper_types.exactly("b.c")]),
          json_value()
        ])

      Properties.check(
        :proper_types.tuple([name(), :proper_types.list(entry)]),
        fn {name, entries} ->
          scope = {:user, name}

          settings =
            Enum.reduce(entries, %{}, fn {k, v}, acc ->
              {:ok, acc} = Rules.put(acc, k, v)
              acc
            end)

          Rules.decode_file(Rules.encode_file(scope, settings), scope) == {:ok, settings}
        end,
        300
      )
    end

    test "property: any text decodes to settings or an error, never a crash" do
      Properties.check(
        :proper_types.oneof([
          :proper_types.binary(),
          Properties.bind(json_value(), fn v ->
            Neptunus.JSON.encode!(%{"user" => "a", "settings" => %{"k" => v}})
          end),
          Properties.bind(json_value(), fn v ->
            Neptunus.JSON.encode!(%{"user" => "a", "settings" => v})
          end)
        ]),
        fn text ->
          case Rules.decode_file(text, {:user, "a"}) do
            {:ok, settings} -> is_map(settings)
            {:error, reason} -> is_binary(reason)
          end
        end,
        300
      )
    end
  end

  defp name do
    Properties.bind(:proper_unicode.utf8(20), fn text ->
      case String.replace(text, ~r/[\x00-\x1f\x7f]/u, "") do
        "" -> "n"
        name -> name
      end
    end)
  end

  defp json_value do
    :proper_types.oneof([
      Properties.json_leaf(),
      :proper_types.list(Properties.json_leaf()),
      Properties.bind(
        :proper_types.list(
          :proper_types.tuple([:proper_unicode.utf8(5), Properties.json_leaf()])
        ),
        &Map.new/1
      )
    ])
  end
end
