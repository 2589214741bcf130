"""Dancing live: a trained run listens to a microphone (or a file played at real-time pace) and
sends each pose as it is made (:mod:`.session`), to OSC receivers and into a recording (:mod:`.sinks`),
with the latency from a frame's audio to its pose measured (:class:`.session.LiveStats`).
docs/live.md describes the command, the OSC address space and the figures."""
