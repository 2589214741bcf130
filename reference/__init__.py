"""Independent references the tests and benchmarks check kinectdata against (not shipped).

- :mod:`.oni_python`: OpenNI's ``.oni`` codecs as plain loops, and a recording writer;
- :mod:`.k4a_writer`: Azure Kinect ``.mkv`` recordings written in k4arecorder's layout, from the
  SDK's recorder source, sharing no code with kinectdata's reader;
- :mod:`.openni`: the real OpenNI libraries (1.x and 2), driven through a small C++ tool and
  the ``openni`` Python bindings, when they are installed.
"""
