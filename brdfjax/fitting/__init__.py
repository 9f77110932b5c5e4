"""The fitting engine, in the order a fit runs: `objective` (Eq. 6 and the exact linear
coefficients), `bounds` (the search box and its unit cube), `evolve` (the genetic search),
`polish` and `marquardt` (Levenberg-Marquardt), `fit` (one fit), `batch` (many fits in one
call) and `cluster` (many fits on a Dask cluster)."""
