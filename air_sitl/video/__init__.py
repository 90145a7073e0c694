"""The camera live: an RTP/H.264 stream over UDP of the downward camera, as PX4 SITL's video.

``options`` parses ``--video`` and its companions; ``encoder`` is the one module that imports
PyAV (FFmpeg's libx264 and its RTP muxer); ``stream`` is the Sink that picks frames from the
simulation and encodes them on a thread of its own; ``overlay`` draws the optional text.
"""
