"""The factor family: certified rightmost roots of every factor of the paper's eq. 3 at many delay pairs.

``rows``    a factor at a delay pair as flat arrays
``seeds``   discretized-generator seeds in stacked eigenvalue calls
``polish``  Halley and Newton steps on q itself, vectorized over rows
``walk``    the argument-principle certificate along lines Re s = c
``solve``   lines, certification and continuation: the drivers
``gains``   the same for many gains at once (gain design)
"""
