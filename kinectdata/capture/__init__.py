"""Recording new takes: a sensor (an OpenNI2 device with NiTE2's skeleton when installed, or an
Azure Kinect / Orbbec Femto through pyk4a) and music from an audio input, stamped on one
monotonic clock (:mod:`.take`; ``kinectdata capture``).

- :mod:`.take`: ``capture_take``, ``read_take``; the ``take.json`` layout (aligning a take:
  :mod:`kinectdata.align.take`);
- :mod:`.sensor`: what a sensor offers a take; :mod:`.openni` (``OpenNI2Sensor``) and :mod:`.k4a`
  (``K4aSensor``): each sensor's recording and how its file is placed on the clock;
- :mod:`.child`: a sensor's session in a child process; :mod:`.openni_session` and
  :mod:`.k4a_session` are those sessions;
- :mod:`.audio`: audio input to WAV with clock stamps (sounddevice).
"""
