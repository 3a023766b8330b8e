"""The live calibrator over Zenoh, ROS 2–compatible without ROS: CDR ``geometry_msgs/msg/WrenchStamped`` in and out.

Key expressions follow zenoh-bridge-ros2dds with its default namespace ``/``: a ROS topic
``/ft/raw`` is the Zenoh key ``ft/raw`` (leading and trailing slashes dropped; the bridge's
``DEFAULT_CONFIG.json5`` documents the namespace as a prefix, so ``namespace: "/robot1"`` would make
it ``robot1/ft/raw``: give ``--wrench-topic /robot1/ft/raw`` then). Payloads are the CDR bytes that
DDS carries and the bridge routes unchanged (serialised with ``rosbags``). With ``keys="rmw_zenoh"`` the
ROS topics use rmw_zenoh's keys instead (``<domain>/<topic>/<type>/<RIHS01 type hash>``, an attachment per
sample, liveliness tokens: :mod:`ftcal.live.rmw_zenoh`); diagnostics and queryables stay plain Zenoh keys.

* subscribes: the raw wrench (``WrenchStamped``), optionally a temperature (``sensor_msgs/msg/Temperature``, checked
  against the model's range and fed to a model with a temperature input) and, optionally, an IMU (``sensor_msgs/msg/Imu``:
  gravity from its orientation, else minus its linear acceleration) or the joint states
  (``sensor_msgs/msg/JointState``, decoded by ``rosbags``; with a robot model,
  :class:`ftcal.robot.kinematics.SensorGravity`, gravity in the sensor frame from the joints named in
  the message, and the joints are the motion signal; wrenches before the first joint state are
  counted and dropped, and a wrench stamped more than :data:`JOINT_MAX_AGE_S` after the newest joint
  state is not static, so the bias never takes up a pose that is out of date). Without either the
  sensor is taken as still in a fixed pose with gravity along its −z axis.
* publishes: ``PREFIX/calibrated`` and ``PREFIX/compensated`` (``WrenchStamped``, the input's header),
  and ``PREFIX/diagnostics`` (JSON: flags with their reasons, the flags raised since the previous message, bias ±
  std, tool, counters) as ROS's ``diagnostic_updater`` does: every :data:`~ftcal.core.limits.LIVE_DIAGNOSTICS_PERIOD_S`
  (1 s) and at once when a flag changes, but no sooner than
  :data:`~ftcal.core.limits.LIVE_DIAGNOSTICS_MIN_INTERVAL_S` after the previous message.
* queryables (Zenoh-native, JSON replies; not ROS services): ``PREFIX/retare``,
  ``PREFIX/switch_tool`` (payload: the tool's name), ``PREFIX/identify_tool`` (payload
  ``start NAME`` or ``finish``), ``PREFIX/status``; all but ``status`` act only on a query for their own key (not a
  wildcard such as ``ft/**``).

What is not Zenoh (pose sources, stamp checks, commands, diagnostics, the main loop) is :mod:`ftcal.live.node_core`'s,
shared with the ROS 2 node.

Each wrench is processed as it arrives, in Zenoh's subscriber callback (zenoh-python's own callback thread: running
it on Zenoh's network thread instead, ``indirect=False``, saved no CPU, and with the low-latency transport stalled
Zenoh's receive path; docs/live.md): decoded with
:mod:`ftcal.live.cdr` (no message objects), one :meth:`~ftcal.live.LiveCalibrator.step` (plain
floats), the two answers encoded with the input's header and put. Handing samples to another
thread through a queue cost a wake-up and a GIL hand-over per message (p99 12.9 ms at 2 kHz); the
main thread now only watches for silence and publishes diagnostics (Python's GIL switch interval stays at
its 5 ms: at 0.2 ms, 4 of 8 runs at 2 kHz under load stalled to a p99 of 68 ms-2 s, against 1 of 8 at
5 ms; docs/live.md). A lock serialises the
calibrator between the callback, the queryables and the diagnostics. No message for ``silence`` s
raises the ``silent`` flag with a one-line message; Ctrl-C and SIGTERM end the loop and the state
is saved. Links use Zenoh's queued transport, whose ``DROP`` loses a stalled consumer's answers rather than blocking
the node (:data:`TRANSPORT_SETTINGS` says why the low-latency one is opt-in).
"""

from __future__ import annotations

import gc
import json
import sys
import time
from dataclasses import dataclass

import numpy as np

from ..core.limits import (LIVE_KEY_CONVENTIONS, LIVE_MAX_QUERY_BYTES, LIVE_MAX_TOPIC_BYTES, MAX_ROS_DOMAIN_ID,
                           MAX_RT_PRIORITY)
from ..runtime.errors import FtcalError, ParameterError
from .cdr import IMU_DOUBLES, TEMPERATURE_DOUBLES, WRENCH_DOUBLES, decode_stamped, encode_like
from .node_core import COMMANDS, JOINT_MAX_AGE_S, MAX_JOINT_LISTS, NodeCore, tool_name  # noqa: F401 (re-exported)

WRENCH_TYPE = "geometry_msgs/msg/WrenchStamped"
IMU_TYPE = "sensor_msgs/msg/Imu"
JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"
TEMPERATURE_TYPE = "sensor_msgs/msg/Temperature"
# Listened on when no endpoint is given: not 7447, the port of the Zenoh router that rmw_zenoh (rmw_zenohd) and
# zenoh-bridge-ros2dds run, so that the node and a router can run side by side.
DEFAULT_ENDPOINT = "tcp/127.0.0.1:7448"
# Listened on beside --connect when no --listen is given (rmw_zenoh's DEFAULT_RMW_ZENOH_SESSION_CONFIG.json5 listens
# on tcp/localhost:0): behind a router, peers reach each other directly, learnt by gossip (see zenoh_config).
EPHEMERAL_ENDPOINT = "tcp/127.0.0.1:0"
# How long the peers given with --connect may take to answer before the node gives up (exit 2, one line).
CONNECT_TIMEOUT_MS = 5000
# Publisher settings (zenoh.Session.declare_publisher keywords; names resolved when zenoh is imported). A late
# answer is dropped rather than the callback blocked (rmw_zenoh's choice for KEEP_LAST topics). Not express:
# measured at 2 kHz, express=True lost 36-407 of 16,000 answers (each message then takes one of the link's two
# queued batches) for no lower p99 (docs/live.md).
PUBLISHER_SETTINGS = {"congestion_control": "DROP"}
# Zenoh's low-latency unicast transport (its DEFAULT_CONFIG.json5: no transmission queue and no batching, each message
# written to the link by the thread that puts it; it cannot keep QoS priorities, so qos must be off). Not the default:
# without a queue there is nothing to drop, so a consumer that stops reading (SIGSTOP, a debugger, a frozen GUI) fills
# its socket and the node's put then blocks: at 2 kHz every answer to every other consumer stopped after about 8 s
# (tested with the queued transport, which drops that consumer's answers instead). Opt in with
# ``ZenohOptions(low_latency=True)`` only where every consumer is trusted to keep reading (docs/live.md).
TRANSPORT_SETTINGS = {"transport/unicast/lowlatency": True, "transport/unicast/qos/enabled": False}


def topic_key(topic: str) -> str:
    """The Zenoh key of a ROS topic under zenoh-bridge-ros2dds (namespace ``/``): ``/ft/raw`` → ``ft/raw``."""
    key = topic.strip("/")
    if not key or any(c in key for c in "*$?#") or "//" in key:
        raise FtcalError(f"topic {topic!r} is not a ROS topic name a Zenoh key can carry.")
    return key


@dataclass(frozen=True)
class ZenohOptions:
    """Endpoints, topics and timing of :func:`serve`, checked when built.

    Raises
    ------
    ParameterError
        Two gravity sources (``imu_topic`` and ``joints_topic``), ``keys`` not one of
        :data:`~ftcal.core.limits.LIVE_KEY_CONVENTIONS`, a ``domain_id`` outside 0 to
        :data:`~ftcal.core.limits.MAX_ROS_DOMAIN_ID` or without ``keys="rmw_zenoh"``, an ``rt_priority`` outside 1 to
        :data:`~ftcal.core.limits.MAX_RT_PRIORITY`.
    """

    listen: tuple[str, ...] = ()
    connect: tuple[str, ...] = ()
    wrench_topic: str = "/ft/raw"
    imu_topic: str | None = None
    joints_topic: str | None = None
    temperature_topic: str | None = None
    prefix: str = "/ft"
    silence: float = 1.0
    duration: float | None = None
    keys: str = "bridge"  # or "rmw_zenoh"
    domain_id: int = 0
    rt_priority: int | None = None  # SCHED_FIFO priority of the node's threads
    low_latency: bool = False  # ask for Zenoh's low-latency transport (TRANSPORT_SETTINGS; a frozen consumer stalls it)

    def __post_init__(self) -> None:
        # Checked here, the one place every caller (workflow.live.serve_zenoh, serve, LiveNode) goes through.
        if self.joints_topic is not None and self.imu_topic is not None:
            raise ParameterError(("imu_topic", "joints_topic", "urdf"),
                                 "give one gravity source: {imu_topic}, or {joints_topic} with {urdf}.")
        if self.keys not in LIVE_KEY_CONVENTIONS:
            raise ParameterError("keys", f"{{keys}} must be {' or '.join(map(repr, LIVE_KEY_CONVENTIONS))}; "
                                         f"got {self.keys!r}.")
        if not 0 <= self.domain_id <= MAX_ROS_DOMAIN_ID:
            raise ParameterError("domain_id", f"{{domain_id}} {self.domain_id}: ROS 2 domain ids go from 0 to "
                                              f"{MAX_ROS_DOMAIN_ID}.")
        if self.domain_id and self.keys != "rmw_zenoh":
            raise ParameterError(("domain_id", "keys"), "{domain_id} goes with {keys} rmw_zenoh "
                                                        "(zenoh-bridge-ros2dds's keys carry no domain).")
        if self.rt_priority is not None and not 1 <= self.rt_priority <= MAX_RT_PRIORITY:
            raise ParameterError("rt_priority", f"{{rt_priority}} {self.rt_priority}: SCHED_FIFO priorities go from 1 "
                                                f"to {MAX_RT_PRIORITY}.")


def zenoh_config(listen=(), connect=(), low_latency: bool = False):
    """A peer configuration: multicast scouting off, explicit endpoints, gossip on (as rmw_zenoh's session config).

    Listens on :data:`DEFAULT_ENDPOINT` when no endpoint is given, and on :data:`EPHEMERAL_ENDPOINT` beside ``connect``
    when only that is given. Gossip is what makes the node work behind a router (``rmw_zenohd``, zenoh-bridge-ros2dds):
    in Zenoh's default ``peer_to_peer`` routing a router does not forward between peers; it tells each peer where the
    others listen (gossip, one hop) and they connect to each other (``autoconnect`` to peers and routers, as rmw_zenoh's
    DEFAULT_RMW_ZENOH_SESSION_CONFIG.json5 does). With gossip off, a peer behind a router received 0 of 100 messages
    (on: 100 of 100); with gossip on but neither peer listening, also 0 (tests/live/test_live_zenoh_router.py). The peers
    in ``connect`` must answer within :data:`CONNECT_TIMEOUT_MS`, else opening the session fails (:func:`open_session`
    says so in one line). ``low_latency``: :data:`TRANSPORT_SETTINGS` (else Zenoh's queued transport)."""
    import zenoh

    config = zenoh.Config()
    config.insert_json5("mode", json.dumps("peer"))
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("scouting/gossip/enabled", "true")
    config.insert_json5("scouting/gossip/multihop", "false")
    config.insert_json5("scouting/gossip/autoconnect", json.dumps({"router": [], "peer": ["router", "peer"]}))
    if not listen:
        listen = (EPHEMERAL_ENDPOINT,) if connect else (DEFAULT_ENDPOINT,)
    config.insert_json5("listen/endpoints", json.dumps(list(listen)))
    config.insert_json5("connect/endpoints", json.dumps(list(connect)))
    if connect:
        config.insert_json5("connect/timeout_ms", json.dumps({"router": CONNECT_TIMEOUT_MS, "peer": CONNECT_TIMEOUT_MS,
                                                              "client": CONNECT_TIMEOUT_MS}))
        config.insert_json5("connect/exit_on_failure", json.dumps({"router": True, "peer": True, "client": True}))
    for key, value in TRANSPORT_SETTINGS.items() if low_latency else ():
        config.insert_json5(key, json.dumps(value))
    return config


def open_session(listen=(), connect=(), low_latency: bool = False):
    """``zenoh.open`` of :func:`zenoh_config`; a port in use or peers that do not answer raise :class:`FtcalError`
    in one line naming the endpoint (zenoh's own error is a paragraph with its source paths)."""
    import zenoh

    try:
        return zenoh.open(zenoh_config(listen, connect, low_latency))
    except zenoh.ZError as exc:
        text = str(exc)
        if "Address already in use" in text or "Can not create a new" in text:
            where = next((e for e in listen or (DEFAULT_ENDPOINT,) if e in text), ", ".join(listen) or DEFAULT_ENDPOINT)
            raise ParameterError(("listen", "connect"), f"{{listen}} {where}: the address is in use (another ftcal "
                                 "live, or a Zenoh router: give {listen} tcp/127.0.0.1:PORT with a free port, or "
                                 "{connect} to that router).") from None
        if "Unable to connect" in text:
            raise ParameterError("connect", f"{{connect}} {', '.join(connect)}: nothing answered within "
                                 f"{CONNECT_TIMEOUT_MS / 1000:g} s (start the router first, e.g. ros2 run "
                                 "rmw_zenoh_cpp rmw_zenohd, or check the endpoint).") from None
        first = text.split(" at /", 1)[0].splitlines()[0] if text else type(exc).__name__
        raise FtcalError(f"Zenoh could not open the session: {first}") from None


def publisher_settings() -> dict:
    """:data:`PUBLISHER_SETTINGS` as zenoh's enum values."""
    import zenoh

    kinds = {"priority": zenoh.Priority, "congestion_control": zenoh.CongestionControl}
    return {name: getattr(kinds[name], value) if name in kinds else value for name, value in PUBLISHER_SETTINGS.items()}


def typestore():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


def wrench_message(store, stamp_ns: int, frame: str, w: np.ndarray) -> bytes:
    """CDR bytes of a ``WrenchStamped``."""
    types = store.types
    header = types["std_msgs/msg/Header"](
        stamp=types["builtin_interfaces/msg/Time"](sec=int(stamp_ns // 1_000_000_000),
                                                  nanosec=int(stamp_ns % 1_000_000_000)), frame_id=frame)
    vec = types["geometry_msgs/msg/Vector3"]
    msg = types[WRENCH_TYPE](header=header, wrench=types["geometry_msgs/msg/Wrench"](
        force=vec(x=float(w[0]), y=float(w[1]), z=float(w[2])), torque=vec(x=float(w[3]), y=float(w[4]),
                                                                        z=float(w[5]))))
    return bytes(store.serialize_cdr(msg, WRENCH_TYPE))


class LiveNode(NodeCore):
    """The calibrator behind Zenoh subscribers, publishers and queryables (see the module docstring)."""

    def __init__(self, live, options: ZenohOptions, *, robot=None, echo=print) -> None:
        if (robot is None) != (options.joints_topic is None):
            raise ParameterError(("joints_topic", "urdf"), "{joints_topic} and a robot model ({urdf}) go together.")
        self.options = options
        for name, topic in (("wrench_topic", options.wrench_topic), ("imu_topic", options.imu_topic),
                            ("joints_topic", options.joints_topic),
                            ("temperature_topic", options.temperature_topic), ("prefix", options.prefix)):
            if topic is not None and len(topic.encode("utf-8", "surrogatepass")) > LIVE_MAX_TOPIC_BYTES:
                raise ParameterError(name, f"{{{name}}}: a topic of {len(topic.encode('utf-8', 'surrogatepass'))} "
                                           f"bytes; at most {LIVE_MAX_TOPIC_BYTES} (ROS 2's limit; Zenoh aborts on much longer keys).")
        self.store = typestore()
        self.topics = {"wrench": (options.wrench_topic, WRENCH_TYPE), "imu": (options.imu_topic, IMU_TYPE),
                       "joints": (options.joints_topic, JOINT_STATE_TYPE),
                       "temperature": (options.temperature_topic, TEMPERATURE_TYPE),
                       "calibrated": (f"{options.prefix.rstrip('/')}/calibrated", WRENCH_TYPE),
                       "compensated": (f"{options.prefix.rstrip('/')}/compensated", WRENCH_TYPE)}
        if options.keys == "rmw_zenoh":
            from .rmw_zenoh import data_key

            ros_key = lambda topic, msgtype: data_key(options.domain_id, topic, msgtype)  # noqa: E731
        else:  # "bridge" (ZenohOptions checked keys)
            ros_key = lambda topic, msgtype: topic_key(topic)  # noqa: E731
        self.keys = {name: None if topic is None else ros_key(topic, msgtype)
                     for name, (topic, msgtype) in self.topics.items()}
        self.keys.update({name: f"{topic_key(options.prefix)}/{name}" for name in
                          ("diagnostics", *COMMANDS)})
        self.attachments: dict = {}  # rmw_zenoh: the attachment of each ROS publisher
        super().__init__(live, robot=robot, echo=echo, source=self.keys["wrench"])

    # ----- Zenoh callbacks (zenoh's threads) ------------------------------------------------------
    def _on_wrench(self, sample) -> None:
        try:
            msg = decode_stamped(sample.payload.to_bytes(), WRENCH_DOUBLES)
        except (ValueError, UnicodeDecodeError):  # a broken message is counted and reported, never fatal
            self.bad_messages += 1
            return
        done = self.process_wrench(msg.stamp_ns, msg.values)
        if done is None:
            return
        result = done[0]
        try:
            if self.attachments:
                now = time.time_ns()
                self.publishers["calibrated"].put(encode_like(msg, result.calibrated.tolist()),
                                                  attachment=self.attachments["calibrated"].next(now))
                self.publishers["compensated"].put(encode_like(msg, result.compensated.tolist()),
                                                   attachment=self.attachments["compensated"].next(now))
            else:
                self.publishers["calibrated"].put(encode_like(msg, result.calibrated.tolist()))
                self.publishers["compensated"].put(encode_like(msg, result.compensated.tolist()))
        except Exception:  # zenoh.ZError once the publishers are undeclared on the way out: the step is done and
            if self.closing:  # saved with the state, only its answer is not sent
                return
            raise
        self.announce(msg.stamp_ns * 1e-9, *done)

    def _on_imu(self, sample) -> None:
        try:
            values = decode_stamped(sample.payload.to_bytes(), IMU_DOUBLES).values
        except (ValueError, UnicodeDecodeError):
            self.bad_messages += 1
            return
        self.take_imu(values[0:4], values[4], values[25:28])

    def _on_temperature(self, sample) -> None:
        try:
            self.take_temperature(decode_stamped(sample.payload.to_bytes(), TEMPERATURE_DOUBLES).values[0])
        except (ValueError, UnicodeDecodeError):
            self.bad_messages += 1

    def _on_joints(self, sample) -> None:
        try:
            msg = self.store.deserialize_cdr(bytes(sample.payload.to_bytes()), JOINT_STATE_TYPE)
            names, positions = tuple(msg.name), np.asarray(msg.position, dtype=float)
            stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        except Exception:  # rosbags raises several kinds on a broken message: counted, never fatal
            self.bad_messages += 1
            return
        self.take_joints(names, positions, stamp, self.keys["joints"])

    def _command(self, query, name: str) -> None:
        """Answer a query to queryable ``name`` with :meth:`~NodeCore.command` on the request's text: every request
        gets one reply.

        An action (every queryable but ``status``) runs only for a query whose key is its own key exactly: a wildcard
        query (``get ft/**``, what a monitoring tool sends to see what answers) reached every queryable and re-tared
        the sensor. Such a query gets no reply from an action; ``status`` answers it."""
        if name != "status" and str(query.key_expr) != self.keys[name]:
            return
        try:
            doc = self.command(name, _payload_text(query))
        except FtcalError as exc:
            doc = {"ok": False, "error": str(exc)}
        query.reply(self.keys[name], json.dumps(doc))  # its own key: the query's may be a wildcard (ft/**)

    # ----- the loop -------------------------------------------------------------------------------
    def serve(self) -> int:
        """Run until ``duration`` elapses (or Ctrl-C / SIGTERM); the state is saved on the way out."""
        import zenoh

        if self.options.rt_priority is not None:
            self._realtime(self.options.rt_priority)
        session = open_session(self.options.listen, self.options.connect, self.options.low_latency)
        entities = []
        try:
            # Publishers first: a subscriber callback may run as soon as it is declared.
            settings = publisher_settings()
            self.publishers = {name: session.declare_publisher(self.keys[name], **settings)
                               for name in ("calibrated", "compensated", "diagnostics")}
            entities += list(self.publishers.values())
            if self.options.keys == "rmw_zenoh":
                entities += self._declare_rmw_zenoh(session)
            if self.keys["imu"]:
                entities.append(session.declare_subscriber(self.keys["imu"], self._on_imu))
            if self.keys["joints"]:
                entities.append(session.declare_subscriber(self.keys["joints"], self._on_joints))
            entities.append(session.declare_subscriber(self.keys["wrench"], self._on_wrench))
            if self.keys["temperature"]:
                entities.append(session.declare_subscriber(self.keys["temperature"], self._on_temperature))
            for name in COMMANDS:
                entities.append(session.declare_queryable(self.keys[name], lambda q, name=name: self._command(q, name)))
            pose = self.keys["imu"] or self.keys["joints"]
            self.echo(f"ftcal live: listening on {self.keys['wrench']}"
                      + (f" and {pose}" if pose else " (no IMU or joints: fixed pose, gravity -z)")
                      + f"; publishing {self.keys['calibrated']}, {self.keys['compensated']}, "
                        f"{self.keys['diagnostics']}", flush=True)
            self.settle()
            self._loop()
        finally:
            self.closing = True  # a callback already running when its subscriber goes may not put any more
            for entity in reversed(entities):  # subscribers and queryables before the publishers they use
                try:
                    entity.undeclare()
                except Exception:  # the session may already be closing
                    pass
            session.close()
            self.save_on_exit()
        return 0

    def settle(self) -> None:
        """After setup, before the first message: collect once, then move every object alive now (modules, the
        model, the type store) out of the collector's sight, so that a collection never walks them mid-stream."""
        gc.collect()
        gc.freeze()

    def _realtime(self, priority: int) -> None:
        """SCHED_FIFO for this thread before the session starts, so that Zenoh's threads inherit it."""
        import os

        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        except (AttributeError, OSError) as exc:  # not Linux, or no CAP_SYS_NICE / rtprio limit
            reason = getattr(exc, "strerror", None) or "not available on this system"
            self.echo(f"ftcal live: --rt-priority {priority}: SCHED_FIFO not permitted ({reason}); running at normal "
                      "priority", file=sys.stderr, flush=True)

    def _declare_rmw_zenoh(self, session) -> list:
        """rmw_zenoh: an attachment per ROS publisher, liveliness tokens for the node and its topics."""
        from .rmw_zenoh import Attachment, liveliness_token

        zid = str(session.zid())
        self.attachments = {name: Attachment(self.keys[name], zid) for name in ("calibrated", "compensated")}
        domain = self.options.domain_id
        tokens = [liveliness_token(domain, zid, 0, "NN")]
        for entity, name in enumerate(("wrench", "imu", "joints", "calibrated", "compensated", "temperature"),
                                      start=1):
            topic, msgtype = self.topics[name]
            if topic is not None:
                kind = "MP" if name in ("calibrated", "compensated") else "MS"
                tokens.append(liveliness_token(domain, zid, entity, kind, topic, msgtype))
        return [session.liveliness().declare_token(token) for token in tokens]

    def _loop(self) -> None:
        self.run_loop(self.options.duration, self.options.silence, self._diagnostics)

    def _diagnostics(self) -> int:
        """Publish the diagnostics message; returns the flag bits it reported."""
        with self.lock:
            flags = self.live.flags_now
            message = self._diagnostics_message()
        self.publishers["diagnostics"].put(message)
        return flags

    def _diagnostics_message(self) -> str:
        """The diagnostics as JSON (:meth:`~NodeCore.diagnostics_status`); starts a new ``raised``."""
        return json.dumps(self.diagnostics_status())


def _payload_text(query) -> str:
    """The request's payload as text: UTF-8, at most :data:`LIVE_MAX_QUERY_BYTES` bytes."""
    payload = query.payload
    data = b"" if payload is None else bytes(payload.to_bytes())
    if len(data) > LIVE_MAX_QUERY_BYTES:
        raise FtcalError(f"the request's payload has {len(data)} bytes; at most {LIVE_MAX_QUERY_BYTES}.")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise FtcalError(f"the request's payload is not UTF-8 text (byte {exc.start}).") from None


def serve(live, options: ZenohOptions, robot=None) -> int:
    """Serve ``live`` over Zenoh until ``options.duration`` (or Ctrl-C / SIGTERM); ``robot``: the joints-to-gravity
    source (:class:`ftcal.robot.kinematics.SensorGravity`) for ``options.joints_topic``."""
    return LiveNode(live, options, robot=robot).serve()
