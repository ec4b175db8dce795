defmodule NeptunusWeb.Endpoint.YawsTest do
  use ExUnit.Case, async: true

  import NeptunusWeb.Endpoint.Yaws

  doctest NeptunusWeb.Endpoint.Yaws

  alias Neptunus.Test.Properties

  defp headers_with(other), do: headers(host: ~c"127.0.0.1:4000", other: other)

  test "header/2 finds a header yaws leaves unparsed, whatever its case, or nil" do
    headers =
      headers_with([
        {:http_header, 0, ~c"X-Other", :undefined, ~c"x"},
        {:http_header, 0, ~c"Origin", :undefined, ~c"http://127.0.0.1:4000"},
        :not_a_header
      ])

    assert header(headers, "origin") == "http://127.0.0.1:4000"
    assert header(headers, "x-other") == "x"
    assert header(headers, "referer") == nil
    assert header(headers_with([]), "origin") == nil
  end

  test "query/1 decodes the query string; none is empty" do
    assert query(arg(querydata: ~c"vsn=2.0.0&name=Ada%20L&token=a%2Bb")) ==
             %{"vsn" => "2.0.0", "name" => "Ada L", "token" => "a+b"}

    assert query(arg(querydata: ~c"a=1&a=2")) == %{"a" => "2"}
    assert query(arg(querydata: :undefined)) == %{}
    assert query(arg(querydata: ~c"")) == %{}
    # malformed escapes are kept as they are
    assert query(arg(querydata: ~c"bad=%zz")) == %{"bad" => "%zz"}
  end

  test "decode_query/1 never raises and gives back what URI.encode_query/1 encoded" do
    Properties.check(:proper_types.binary(), fn text -> is_map(decode_query(text)) end)

    pairs =
      :proper_types.list(
        :proper_types.tuple([
          Properties.bind(
            :proper_types.non_empty(:proper_types.list(:proper_types.range(1, 0x10FFFF))),
            &safe_string/1
          ),
          Properties.bind(:proper_types.list(:proper_types.range(0, 0x10FFFF)), &safe_string/1)
        ])
      )

    Properties.check(pairs, fn pairs ->
      map = Map.new(pairs)
      decode_query(map |> URI.encode_query() |> String.to_charlist()) == map
    end)
  end

  # code points a string may hold (no surrogates)
  defp safe_string(code_points),
    do: code_points |> Enum.reject(&(&1 in 0xD800..0xDFFF)) |> List.to_string()

  test "text/1 reads a record's text field" do
    assert text(~c"127.0.0.1") == "127.0.0.1"
    assert text("already") == "already"
    assert text(:undefined) == nil
  end
end
