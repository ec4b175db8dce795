defmodule NeptunusWeb.Socket.WsFrameTest do
  use ExUnit.Case, async: true

  alias Neptunus.Test.Properties
  alias NeptunusWeb.Socket.WsFrame

  doctest WsFrame

  # RFC 6455 §5.2, read independently of the encoder: {fin, opcode, masked, payload, rest}
  defp parse(<<fin::1, _rsv::3, opcode::4, mask::1, len::7, rest::binary>>) do
    {len, rest} =
      case len do
        126 ->
          <<n::16, r::binary>> = rest
          {n, r}

        127 ->
          <<0::1, n::63, r::binary>> = rest
          {n, r}

        n ->
          {n, rest}
      end

    <<payload::binary-size(len), rest::binary>> = rest
    {fin, opcode, mask, payload, rest}
  end

  test "a final, unmasked text frame carrying the payload, at every length form's edges" do
    for size <- [0, 1, 125, 126, 127, 65_535, 65_536, 200_000] do
      payload = :binary.copy("a", size)
      assert {1, 1, 0, ^payload, ""} = parse(IO.iodata_to_binary(WsFrame.text(payload)))
    end
  end

  test "the payload is the caller's binary, not a copy" do
    payload = :binary.copy("x", 1_000)
    [_header, sent] = WsFrame.text(payload)
    # the same off-heap binary: :binary.referenced_byte_size/1 and identity of the data
    assert :erts_debug.same(sent, payload)
  end

  test "the shortest length form is used" do
    assert byte_size(WsFrame.header(125)) == 2
    assert byte_size(WsFrame.header(126)) == 4
    assert byte_size(WsFrame.header(65_535)) == 4
    assert byte_size(WsFrame.header(65_536)) == 10
  end

  test "a size no frame can carry is refused" do
    for bad <- [-1, 0x8000_0000_0000_0000, 1.5, nil] do
      assert_raise ArgumentError, fn -> WsFrame.header(bad) end
    end
  end

  test "property: any payload comes back whole from its frame" do
    Properties.check(:proper_types.binary(), fn payload ->
      parse(IO.iodata_to_binary(WsFrame.text(payload))) == {1, 1, 0, payload, ""}
    end)
  end

  test "property: header sizes of any length round-trip" do
    gen = :proper_types.integer(0, 0x7FFF_FFFF_FFFF_FFFF)

    Properties.check(gen, fn size ->
      header = WsFrame.header(size)

      case header do
        <<0x81, n, rest::binary>> when n < 126 -> n == size and rest == ""
        <<0x81, 126, n::16>> -> n == size and size > 125
        <<0x81, 127, 0::1, n::63>> -> n == size and size > 65_535
        _ -> false
      end
    end)
  end
end
