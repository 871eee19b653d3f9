"""Deploying a manager on an SSL stack: SSL-Vision packets in, robot commands out.

- ``wire``: protocol messages to and from bytes (``proto/``: the ``.proto`` files and generated modules);
- ``tracker``: detections from several cameras -> filtered pose and velocity, predicted to the send time;
- ``view``: the core's observation, decoding and worker on tracked robots (or an exported file);
- ``controller``: one control period, with the stop for robots not seen;
- ``net`` and ``loop``: sockets, the real-time loop, the loopback control socket for targets;
- ``assemble``: the pieces put together from command-line values;
- ``field``: a loopback field server on hier_ssl's own world, with ``cameras`` its cameras and
  ``field_referee`` its referee and foul counting;
- ``bench``: latency and through-the-wire success (``hier-ssl bench deploy``), ``wired`` a field server
  and the loop run together for them.

Needs the ``deploy`` extra (``protobuf``).
"""
