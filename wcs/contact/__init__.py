"""Contact: a solve's data (`problem`), the friction laws that drive it (`laws`), the methods
by name (`methods`: the condensed semismooth Newton `solver`, the cvxpy reference `qp`)."""
