defmodule Neptunus.Dynamics.Linear do
  @moduledoc """
  Small dense linear algebra on lists of rows, for building the model's constant matrices
  once (`Neptunus.Dynamics.Params`). Not used in the integration loop, which works on
  flattened tuples.
  """

  @type vector :: [float()]
  @type matrix :: [vector()]

  @doc """
  Diagonal matrix.

      iex> Neptunus.Dynamics.Linear.diagonal([1.0, 2.0])
      [[1.0, 0.0], [0.0, 2.0]]
  """
  @spec diagonal([number()]) :: matrix()
  def diagonal(values) do
    n = length(values)

    values
    |> Enum.with_index()
    |> Enum.map(fn {value, i} -> List.duplicate(0.0, n) |> List.replace_at(i, value * 1.0) end)
  end

  @doc "Element-wise sum."
  @spec add(matrix(), matrix()) :: matrix()
  def add(a, b), do: Enum.zip_with(a, b, fn ra, rb -> Enum.zip_with(ra, rb, &(&1 + &2)) end)

  @doc "Matrix times vector."
  @spec mat_vec(matrix(), vector()) :: vector()
  def mat_vec(m, v),
    do: Enum.map(m, fn row -> row |> Enum.zip_with(v, &(&1 * &2)) |> Enum.sum() end)

  @doc "Matrix product."
  @spec mul(matrix(), matrix()) :: matrix()
  def mul(a, b) do
    cols = transpose(b)
    Enum.map(a, fn row -> Enum.map(cols, fn col -> dot(row, col) end) end)
  end

  @doc "Transpose."
  @spec transpose(matrix()) :: matrix()
  def transpose(m), do: m |> Enum.zip() |> Enum.map(&Tuple.to_list/1)

  @doc "Dot product."
  @spec dot(vector(), vector()) :: float()
  def dot(a, b), do: a |> Enum.zip_with(b, &(&1 * &2)) |> Enum.sum()

  @doc """
  Skew-symmetric matrix `S(a)` with `S(a) b = a × b`.

      iex> Neptunus.Dynamics.Linear.skew([1.0, 2.0, 3.0])
      [[0.0, -3.0, 2.0], [3.0, 0.0, -1.0], [-2.0, 1.0, 0.0]]
  """
  @spec skew(vector()) :: matrix()
  def skew([a1, a2, a3]), do: [[0.0, -a3, a2], [a3, 0.0, -a1], [-a2, a1, 0.0]]

  @doc "Cross product `a × b`."
  @spec cross(vector(), vector()) :: vector()
  def cross([a1, a2, a3], [b1, b2, b3]),
    do: [a2 * b3 - a3 * b2, a3 * b1 - a1 * b3, a1 * b2 - a2 * b1]

  @doc "The 6×6 matrix `[[a, b], [c, d]]` from four 3×3 blocks."
  @spec blocks(matrix(), matrix(), matrix(), matrix()) :: matrix()
  def blocks(a, b, c, d), do: Enum.zip_with(a, b, &(&1 ++ &2)) ++ Enum.zip_with(c, d, &(&1 ++ &2))

  @doc "Scales every element."
  @spec scale(matrix(), float()) :: matrix()
  def scale(m, k), do: Enum.map(m, fn row -> Enum.map(row, &(&1 * k)) end)

  @doc "The square sub-matrix on the given row/column indices."
  @spec take(matrix(), [non_neg_integer()]) :: matrix()
  def take(m, indices) do
    Enum.map(indices, fn i ->
      row = Enum.at(m, i)
      Enum.map(indices, &Enum.at(row, &1))
    end)
  end

  @doc "Whether a symmetric matrix is positive definite (Cholesky succeeds)."
  @spec positive_definite?(matrix()) :: boolean()
  def positive_definite?(m) do
    n = length(m)
    a = m |> Enum.with_index() |> Map.new(fn {row, i} -> {i, List.to_tuple(row)} end)

    Enum.reduce_while(0..(n - 1), %{}, fn j, l ->
      diag = elem(a[j], j) - Enum.sum(for k <- 0..(j - 1)//1, do: l[{j, k}] * l[{j, k}])

      if diag <= 1.0e-12 do
        {:halt, :error}
      else
        ljj = :math.sqrt(diag)
        l = Map.put(l, {j, j}, ljj)

        l =
          Enum.reduce((j + 1)..(n - 1)//1, l, fn i, l ->
            s = elem(a[i], j) - Enum.sum(for k <- 0..(j - 1)//1, do: l[{i, k}] * l[{j, k}])
            Map.put(l, {i, j}, s / ljj)
          end)

        {:cont, l}
      end
    end) != :error
  end

  @doc """
  Inverse by Gauss–Jordan elimination with partial pivoting. Raises `ArgumentError` on a
  singular matrix.

      iex> Neptunus.Dynamics.Linear.invert([[2.0, 0.0], [0.0, 4.0]])
      [[0.5, 0.0], [0.0, 0.25]]
  """
  @spec invert(matrix()) :: matrix()
  def invert(a) do
    n = length(a)
    identity = diagonal(List.duplicate(1.0, n))
    augmented = Enum.zip_with(a, identity, &(&1 ++ &2))

    0..(n - 1)
    |> Enum.reduce(augmented, fn col, rows ->
      {pivot_row, pivot_index} =
        rows
        |> Enum.with_index()
        |> Enum.drop(col)
        |> Enum.max_by(fn {row, _} -> abs(Enum.at(row, col)) end)

      pivot = Enum.at(pivot_row, col)
      if abs(pivot) < 1.0e-12, do: raise(ArgumentError, "matrix is singular")

      normalised = Enum.map(pivot_row, &(&1 / pivot))

      rows
      |> List.replace_at(pivot_index, Enum.at(rows, col))
      |> List.replace_at(col, normalised)
      |> Enum.with_index()
      |> Enum.map(fn
        {row, ^col} ->
          row

        {row, _} ->
          factor = Enum.at(row, col)
          Enum.zip_with(row, normalised, fn x, y -> x - factor * y end)
      end)
    end)
    |> Enum.map(&Enum.drop(&1, n))
  end
end
