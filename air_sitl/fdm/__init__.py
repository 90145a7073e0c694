"""Flight dynamics: the FlightModel protocol and the JSBSim adapter (the only jsbsim importer)."""
