"""ROS 2 on the bus without ROS 2: samples laid out exactly as rmw_zenoh lays them out.

:mod:`~air_sitl.bus.ros2.layout` holds rmw_zenoh's layout (keys, liveliness tokens, GIDs,
attachments, with the design document and source files each comes from);
:mod:`~air_sitl.bus.ros2.messages` builds and reads the messages (rosbags: CDR and RIHS01
hashes of each distro), :mod:`~air_sitl.bus.ros2.node` is one node on a session and
:mod:`~air_sitl.bus.ros2.view` the vehicle's node (``--ros2``). docs/ros2.md tells a user.
"""
