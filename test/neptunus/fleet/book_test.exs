defmodule Neptunus.Fleet.BookTest do
  use ExUnit.Case, async: true

  alias Neptunus.Fleet.Book

  @local :"top@127.0.0.1"
  @v :"rov1@127.0.0.1"

  defp pid(n), do: :c.pid(0, n, 0)

  test "a joined vehicle is up with its node, board and helm" do
    {book, []} = Book.join(Book.new(), "rov", :simulated, pid(1), @v, @local)

    assert Book.lookup(book, "rov") == %{
             id: "rov",
             board: :simulated,
             node: @v,
             pid: pid(1),
             status: :up
           }

    assert Book.entries(book) == [Book.lookup(book, "rov")]
    assert Book.lookup(book, "other") == nil
  end

  test "a helm that leaves while its node is connected: the vehicle is no longer listed" do
    {book, []} = Book.join(Book.new(), "rov", :simulated, pid(1), @v, @local)
    assert {book, []} = Book.leave(book, "rov", pid(1), true)
    assert Book.entries(book) == []
    assert Book.lookup(book, "rov") == nil
    # and back when it starts again
    {book, []} = Book.join(book, "rov", :simulated, pid(2), @v, @local)
    assert %{status: :up} = Book.lookup(book, "rov")
  end

  test "a node that shuts down (its vehicles stop first, then it goes): unreachable, announced" do
    {book, []} = Book.join(Book.new(), "rov", :simulated, pid(1), @v, @local)
    {book, []} = Book.join(book, "other", :simulated, pid(2), :"rov2@127.0.0.1", @local)
    {book, []} = Book.leave(book, "rov", pid(1), true)
    {book, [{:unreachable, "rov", @v}]} = Book.nodedown(book, @v)
    assert %{status: :unreachable, node: @v} = Book.lookup(book, "rov")
    assert %{status: :up} = Book.lookup(book, "other")
  end

  test "a helm that leaves with its node cut off: unreachable, announced once, then back" do
    {book, []} = Book.join(Book.new(), "rov", :simulated, pid(1), @v, @local)
    {book, [{:unreachable, "rov", @v}]} = Book.leave(book, "rov", pid(1), false)
    assert %{status: :unreachable, pid: nil, node: @v} = Book.lookup(book, "rov")
    # the nodedown that follows announces nothing more
    assert {^book, []} = Book.nodedown(book, @v)
    {book, [{:reachable, "rov", @v}]} = Book.join(book, "rov", :simulated, pid(2), @v, @local)
    assert %{status: :up, pid: pid} = Book.lookup(book, "rov")
    assert pid == pid(2)
  end

  test "nodedown first: every vehicle of that node unreachable; the late leave changes nothing" do
    {book, []} = Book.join(Book.new(), "a", :simulated, pid(1), @v, @local)
    {book, []} = Book.join(book, "b", :sitl, pid(2), @v, @local)
    {book, []} = Book.join(book, "c", :simulated, pid(3), :"rov2@127.0.0.1", @local)
    {book, announced} = Book.nodedown(book, @v)
    assert Enum.sort(announced) == [{:unreachable, "a", @v}, {:unreachable, "b", @v}]
    assert {^book, []} = Book.leave(book, "a", pid(1), false)
    assert %{status: :up} = Book.lookup(book, "c")
    assert Book.forget(book, @v) |> Book.entries() |> Enum.map(& &1.id) == ["c"]
  end

  test "a stale pid's leave does not remove the vehicle's newer helm" do
    {book, []} = Book.join(Book.new(), "rov", :simulated, pid(1), @v, @local)
    {book, []} = Book.join(book, "rov", :simulated, pid(2), @v, @local)
    assert {^book, []} = Book.leave(book, "rov", pid(1), true)
  end

  test "this node's vehicle wins over a remote one of the same id" do
    {book, []} = Book.join(Book.new(), "rov", :simulated, pid(1), @local, @local)
    assert {^book, []} = Book.join(book, "rov", :simulated, pid(2), @v, @local)
  end

  test "a node renamed (distributed after its vehicles joined) keeps its vehicles as its own" do
    {book, []} = Book.join(Book.new(), "rov", :simulated, pid(1), :nonode@nohost, :nonode@nohost)
    {book, []} = Book.join(book, "far", :simulated, pid(2), @v, :nonode@nohost)
    book = Book.rename(book, :nonode@nohost, @local)

    assert %{node: @local, status: :up} = Book.lookup(book, "rov")
    assert %{node: @v} = Book.lookup(book, "far")
    # still this node's: a remote vehicle of the same id does not take its place
    assert {^book, []} = Book.join(book, "rov", :simulated, pid(3), @v, @local)
  end
end
