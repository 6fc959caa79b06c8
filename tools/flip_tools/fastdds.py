"""The Fast DDS default profile every process of a graph gets (FASTRTPS_DEFAULT_PROFILES_FILE, unless
the environment names one): see :mod:`flip_tools.launcher`'s module doc."""
from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

PROFILES_ENV = "FASTRTPS_DEFAULT_PROFILES_FILE"
#: SHM: 16 MiB segment per participant, 16,384-message port queue (~4,000 lockstep steps for the
#: recorder, which takes ~4 messages a step); UDP bound to loopback; participants announced every
#: 0.5 s instead of Fast DDS's 3 s: the simulator and the recorder (started before it) matched only
#: at the first periodic announcement, ~2.6-2.9 s after the simulator's start, which every run
#: waited for (`flip stand`: graph ready 3.45-3.79 s; 1.41 s with 0.5 s)
FASTDDS_PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <transport_descriptors>
    <transport_descriptor>
      <transport_id>shm_deep</transport_id>
      <type>SHM</type>
      <segment_size>16777216</segment_size>
      <port_queue_capacity>16384</port_queue_capacity>
    </transport_descriptor>
    <transport_descriptor>
      <transport_id>udp_loopback</transport_id>
      <type>UDPv4</type>
      <interfaceWhiteList><address>127.0.0.1</address></interfaceWhiteList>
    </transport_descriptor>
  </transport_descriptors>
  <participant profile_name="flip_graph" is_default_profile="true">
    <rtps>
      <userTransports>
        <transport_id>shm_deep</transport_id>
        <transport_id>udp_loopback</transport_id>
      </userTransports>
      <useBuiltinTransports>false</useBuiltinTransports>
      <builtin>
        <discovery_config>
          <leaseAnnouncement><sec>0</sec><nanosec>500000000</nanosec></leaseAnnouncement>
        </discovery_config>
      </builtin>
    </rtps>
  </participant>
</profiles>
"""


def fastdds_profile_file() -> str:
    """FASTDDS_PROFILE written once to the temp directory (named by its content)."""
    digest = hashlib.sha1(FASTDDS_PROFILE.encode()).hexdigest()[:12]
    path = Path(tempfile.gettempdir()) / f"flip-fastdds-{digest}.xml"
    if not path.exists():
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(FASTDDS_PROFILE)
        tmp.replace(path)
    return str(path)
