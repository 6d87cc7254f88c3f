"""Analysis of the characteristic equation: CTCR stability maps and characteristic roots."""
