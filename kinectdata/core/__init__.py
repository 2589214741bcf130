"""What every layer stands on: errors, shipped resources and JSON Schemas, atomic writes, hashes,
headless figures, and the motion container with its joint sets and quaternion helpers.

- :mod:`.errors`: the exception and warning classes every module raises;
- :mod:`.resources`: shipped schema files, by name or path, and their validation;
- :mod:`.atomic`: files and HDF5 written through a temporary name and renamed;
- :mod:`.hashing`: SHA-256 of files and folders (provenance, manifests);
- :mod:`.figures`: matplotlib headless, PNGs written atomically;
- :mod:`.motion`: :class:`~.motion.Motion`, one recording's poses ([T, J, 3] metres or pixels,
  [T, J, 4] xyzw quaternions, confidence, masks) and its joint set;
- :mod:`.jointsets`: joint sets as data files (names, parents, hierarchy);
- :mod:`.quaternions`: xyzw/wxyz order, sign continuity, averages.
"""
