"""Contact solvers: the condensed semismooth Newton method (`solver`) and the cvxpy reference (`qp`)."""
