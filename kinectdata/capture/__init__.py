"""Recording new takes: an OpenNI2 sensor (with NiTE2's skeleton when installed) and music from
an audio input, stamped on one monotonic clock (:mod:`.take`; ``kinectdata capture``).

- :mod:`.take`: ``capture_take``, ``read_take``; the ``take.json`` layout (aligning a take:
  :mod:`kinectdata.align.take`);
- :mod:`.openni_session`: the OpenNI2 recording, run in a child process;
- :mod:`.audio`: audio input to WAV with clock stamps (sounddevice).
"""
