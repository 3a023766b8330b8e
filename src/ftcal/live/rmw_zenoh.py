"""rmw_zenoh's naming on the wire: data key expressions with the RIHS01 type hash, the per-sample attachment, and
the liveliness tokens by which ROS 2 nodes on rmw_zenoh discover each other.

* Data key: ``<domain_id>/<topic without its leading and trailing slashes>/<DDS type name>/<type hash>``, e.g.
  ``0/ft/raw/geometry_msgs::msg::dds_::WrenchStamped_/RIHS01_8dc3…``. The DDS type name is
  ``<package>::msg::dds_::<Type>_``; the type hash is REP-2011's RIHS01, the SHA-256 of the canonical JSON
  of the type description, computed by ``rosbags`` (``Typestore.hash_rihs01``) from the message definitions
  it ships. tests/live/test_live_rmw_zenoh.py checks the hashes against values published in ROS 2 sources.
* Attachment of every sample (rmw_zenoh_cpp ``attachment_helpers.cpp``, zenoh's ``ze_serializer``): the
  string ``sequence_number`` then an int64, ``source_timestamp`` then an int64 (ns), ``source_gid`` then 16
  bytes; a string or a byte buffer is a LEB128 length and its bytes, an int64 is 8 little-endian bytes.
* Liveliness tokens (``@ros2_lv/<domain>/<session id>/<node id>/<entity id>/<kind>/<enclave>/<namespace>/
  <node>[/<topic>/<type>/<hash>/<qos>]``, slashes in names replaced by ``%``, ``%`` for an empty namespace or
  enclave): one for the node, one per publisher (``MP``) and subscription (``MS``), so ``ros2 topic list`` on
  rmw_zenoh can see the node. Their layout follows rmw_zenoh's ``liveliness_utils.cpp``; unlike the data keys
  and the attachment, they were not checked against a running ROS 2 graph here (no ROS on this machine).
"""

from __future__ import annotations

import hashlib
import struct
from functools import lru_cache

from ..runtime.errors import FtcalError

ADMIN_SPACE = "@ros2_lv"
NODE_NAME = "ftcal_live"
# QoS of the liveliness tokens: rmw_zenoh's compact form with every policy at its default and depth 10
# (reliable, volatile, keep last), as ROS 2's default publisher profile.
DEFAULT_QOS = "::,10:,:,:,,"
_INT64 = struct.Struct("<q")


def _leb128(n: int) -> bytes:
    out = bytearray()
    while True:
        byte, n = n & 0x7F, n >> 7
        out.append(byte | (0x80 if n else 0))
        if not n:
            return bytes(out)


def _zbytes(data: bytes) -> bytes:
    return _leb128(len(data)) + data


@lru_cache(maxsize=None)
def type_hash(msgtype: str) -> str:
    """The RIHS01 hash of a ROS 2 message type, e.g. ``geometry_msgs/msg/WrenchStamped``."""
    from rosbags.typesys import Stores, get_typestore

    try:
        return get_typestore(Stores.ROS2_JAZZY).hash_rihs01(msgtype)
    except Exception as exc:  # rosbags raises its own error kinds for an unknown type
        raise FtcalError(f"no message definition for {msgtype!r} to hash: {exc}") from None


def dds_type_name(msgtype: str) -> str:
    """``geometry_msgs/msg/WrenchStamped`` → ``geometry_msgs::msg::dds_::WrenchStamped_``."""
    package, kind, name = msgtype.split("/")
    return f"{package}::{kind}::dds_::{name}_"


def _topic(topic: str) -> str:
    name = topic.strip("/")
    if not name or any(c in name for c in "*$?#%") or "//" in name:
        raise FtcalError(f"topic {topic!r} is not a ROS topic name a Zenoh key can carry.")
    return name


def data_key(domain_id: int, topic: str, msgtype: str) -> str:
    """rmw_zenoh's key expression of a topic's data."""
    return f"{domain_id}/{_topic(topic)}/{dds_type_name(msgtype)}/{type_hash(msgtype)}"


def liveliness_token(domain_id: int, session_id: str, entity_id: int, kind: str, topic: str | None = None,
                     msgtype: str | None = None) -> str:
    """The liveliness key of the node (``kind`` ``NN``), a publisher (``MP``) or a subscription (``MS``)."""
    key = f"{ADMIN_SPACE}/{domain_id}/{session_id}/0/{entity_id}/{kind}/%/%/{NODE_NAME}"
    if topic is not None:
        key += f"/%{_topic(topic).replace('/', '%')}/{dds_type_name(msgtype)}/{type_hash(msgtype)}/{DEFAULT_QOS}"
    return key


class Attachment:
    """The attachment of one publisher's samples: a running sequence number, the time and the publisher's GID."""

    def __init__(self, key: str, session_id: str) -> None:
        # A GID is 16 bytes that identify the publisher; derived from the session and key, stable for a run.
        self.gid = hashlib.sha256(f"{session_id}/{key}".encode()).digest()[:16]
        self.sequence = 0
        self._seq = _zbytes(b"sequence_number")
        self._stamp = _zbytes(b"source_timestamp")
        self._tail = _zbytes(b"source_gid") + _zbytes(self.gid)

    def next(self, timestamp_ns: int) -> bytes:
        """The bytes for the next sample, stamped ``timestamp_ns`` (rmw_zenoh uses the system clock)."""
        self.sequence += 1
        return self._seq + _INT64.pack(self.sequence) + self._stamp + _INT64.pack(timestamp_ns) + self._tail
