"""The PX4-like MAVLink vehicle endpoint.

``messages`` and ``mission_protocol`` are pure (no pymavlink, no sockets); ``codec`` is the only
module that imports pymavlink; ``links`` owns the sockets; ``vehicle`` ties them to a flight.
"""
