defmodule Neptunus.Navigation.Matrix do
  @moduledoc """
  The few dense-matrix operations the position filter needs, on lists of rows of floats (its
  matrices are at most 4×4: a library would cost more than it saves). Pure.

      iex> alias Neptunus.Navigation.Matrix, as: M
      iex> M.mul([[1.0, 2.0], [3.0, 4.0]], [[0.0, 1.0], [1.0, 0.0]])
      [[2.0, 1.0], [4.0, 3.0]]
      iex> M.inv2([[2.0, 0.0], [0.0, 4.0]])
      [[0.5, 0.0], [0.0, 0.25]]
  """

  @type t :: [[float()]]
  @type vector :: [float()]

  @doc "The n×n identity."
  @spec identity(pos_integer()) :: t()
  def identity(n), do: for(i <- 1..n, do: for(j <- 1..n, do: if(i == j, do: 1.0, else: 0.0)))

  @doc "A diagonal matrix."
  @spec diag(vector()) :: t()
  def diag(values) do
    n = length(values)

    values
    |> Enum.with_index()
    |> Enum.map(fn {v, i} -> for j <- 0..(n - 1), do: if(i == j, do: v * 1.0, else: 0.0) end)
  end

  @doc "The transpose."
  @spec transpose(t()) :: t()
  def transpose(m), do: m |> Enum.zip() |> Enum.map(&Tuple.to_list/1)

  @doc "The product `a · b`."
  @spec mul(t(), t()) :: t()
  def mul(a, b) do
    bt = transpose(b)
    for row <- a, do: for(col <- bt, do: dot(row, col))
  end

  @doc "The product `m · v` of a matrix and a vector."
  @spec mulv(t(), vector()) :: vector()
  def mulv(m, v), do: Enum.map(m, &dot(&1, v))

  @doc "The dot product."
  @spec dot(vector(), vector()) :: float()
  def dot(a, b), do: a |> Enum.zip(b) |> Enum.reduce(0.0, fn {x, y}, acc -> acc + x * y end)

  @doc "`a + b`."
  @spec add(t(), t()) :: t()
  def add(a, b), do: zip_with(a, b, &+/2)

  @doc "`a − b`."
  @spec sub(t(), t()) :: t()
  def sub(a, b), do: zip_with(a, b, &-/2)

  @doc "`k · m`."
  @spec scale(t(), float()) :: t()
  def scale(m, k), do: Enum.map(m, fn row -> Enum.map(row, &(&1 * k)) end)

  @doc "`(m + mᵀ) / 2`: keeps a covariance symmetric against rounding."
  @spec symmetric(t()) :: t()
  def symmetric(m), do: m |> add(transpose(m)) |> scale(0.5)

  @doc "The inverse of a 2×2 matrix (nil when singular)."
  @spec inv2(t()) :: t() | nil
  def inv2([[a, b], [c, d]]) do
    det = a * d - b * c

    if abs(det) < 1.0e-300,
      do: nil,
      else: [[d / det, -b / det], [-c / det, a / det]]
  end

  @doc "Element (i, j), zero-based."
  @spec at(t(), non_neg_integer(), non_neg_integer()) :: float()
  def at(m, i, j), do: m |> Enum.at(i) |> Enum.at(j)

  @doc "The square block of `m` from row and column `from` to `to` (zero-based, inclusive)."
  @spec block(t(), non_neg_integer(), non_neg_integer()) :: t()
  def block(m, from, to), do: m |> Enum.slice(from..to) |> Enum.map(&Enum.slice(&1, from..to))

  @doc """
  A 2×2 covariance's 1-σ ellipse: `{major, minor, angle}` — the semi-axes (square roots of
  the eigenvalues) and the major axis' direction (rad, from the first axis towards the
  second: from north towards east for a north/east covariance).
  """
  @spec ellipse(t()) :: {float(), float(), float()}
  def ellipse([[a, b], [_, c]]) do
    mean = (a + c) / 2
    radius = :math.sqrt(max((a - c) * (a - c) / 4 + b * b, 0.0))
    l1 = max(mean + radius, 0.0)
    l2 = max(mean - radius, 0.0)
    angle = 0.5 * :math.atan2(2 * b, a - c)
    {:math.sqrt(l1), :math.sqrt(l2), angle}
  end

  defp zip_with(a, b, f) do
    Enum.zip_with(a, b, fn ra, rb -> Enum.zip_with(ra, rb, f) end)
  end
end
