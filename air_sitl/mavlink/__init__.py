"""The PX4-like MAVLink vehicle endpoint.

``messages`` and ``mission_protocol`` are pure (no pymavlink, no sockets); ``codec`` is the only
module that imports pymavlink; ``links`` owns the sockets; ``vehicle`` ties them to a flight
(I/O thread, dispatch table, mission protocol) with its parts: ``commands`` (COMMAND_LONG/INT),
``param_protocol`` (PARAM_*), ``streams`` (telemetry scheduling and builders), ``camera``
(component 100: camera and video protocols), ``telemetry`` (message contents) and
``interfaces`` (the types they share, among them ``EndpointLike``: the parts see the endpoint
through it and never import ``vehicle``, so imports point one way).
"""
