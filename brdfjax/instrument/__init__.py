"""Driving a goniometer like the paper's and feeding its measurements to the fitter.

The modules, in the order data flow through them:

- `brdfjax.instrument.protocol`: the line protocol (framing, CRC-16, replies, commands) and
  what motors A, B and C turn; its docstring is the protocol's specification.
- `brdfjax.instrument.driver`: `Instrument`, the pyserial client, with retries and
  `InstrumentError` subclasses that say what the instrument did or did not answer.
- `brdfjax.instrument.simulator`: a simulated instrument on a pseudo-terminal (model or data
  BRDF, PTFE reference plate, motor travel, noise, fault injection).
- `brdfjax.instrument.plan`: `Plan`, what to measure, from options or a TOML file.
- `brdfjax.instrument.acquire`: `measure`, the journaled, resumable acquisition that writes
  a measurement file by the reference-sample method, Eq. (7)-(8).
- `brdfjax.instrument.design`: `plan`, which geometries to read next (integrated variance of
  the learned discrepancy, or space-filling from nothing) and the route for the motors.
- `brdfjax.instrument.adaptive`: `measure_adaptive`, the closed loop of plan, measure and
  predict that stops when the prediction is as narrow as asked.

The driver needs pyserial (``pip install brdfjax[instrument]``); the simulator does not.
"""
