"""ROS 2 services on DDS, as rmw_cyclonedds serves them: what ``~/list_parameters`` and ``~/stop`` answer on.

A service ``/ns/hcrctl/stop`` is a reader of ``rq/ns/hcrctl/stopRequest`` and
a writer of ``rr/ns/hcrctl/stopReply`` (reliable, volatile, keep last 10:
rmw's service QoS). rmw_cyclonedds puts a header before the request's fields
(the client's id, the request's number) and the reply carries it back, which
is how a client knows its own answer among everyone's: this node speaks that,
the only way a Cyclone DDS node can (``idl.service_type``).

rmw_fastrtps (eProsima Fast DDS, ROS 2's default) does not: its client takes
a reply only when the reply's RTPS inline QoS names the request
(``related_sample_identity``), which Cyclone DDS has no way to send. So a
Fast DDS client sees these services (``ros2 service list``) but its calls are
never answered; a request without rmw_cyclonedds's header is not one of this
node's and goes unanswered. docs/ros2.md says so.

Nothing a client does keeps a stop from running:

- An ordinary request (the parameters) is taken on the node's intake thread
  and queued for one worker, which answers them in order; beyond
  ``MAX_WAITING`` waiting, a burst is dropped (a client retries).
- A first-served one (``serve_first``: ``~/stop``) has a reader, an intake
  thread and a worker of its own: its ``act`` (the governor's stop) runs on
  that intake thread the moment the request is taken, and its answer (which
  waits for the robot) is made on its worker; no other request shares any of
  them.
- A reply waits for the client's reply reader to be matched (discovery is
  two-sided: a request may come before this node's reply writer has learnt
  the client's reader, and a volatile reply written then reaches no one),
  but never in a worker: ``Replies`` holds it (at most ``MAX_PENDING``, at
  most ``MATCH_WAIT`` each) and writes it once the reader is there, so an
  asker with no reply reader costs a slot for a while, and nothing else.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from ..protocol import ros2conv, ros2msg, ros2srv
from ..served.notes import Level
from . import idl
from .intake import Intake
from .node import Node, Note, dds_qos, reader_qos
from .worker import CLOSE_WAIT, MAX_FIRST, MAX_WAITING, Worker

#: rmw's default service QoS.
SERVICE_QOS = ros2conv.Qos(reliable=True, transient_local=False, depth=10)


class Request(dict[str, Any]):
    """A request's own fields (the header left out), and who asked: the ROS 2 node that owns the client's
    request writer, as the graph (``ros_discovery_info``) names it; None where no rmw announced it (a raw
    DDS peer). A name any participant may announce: it says who, it proves nothing."""

    def __init__(self, fields: dict[str, Any], asker: str | None = None) -> None:
        super().__init__(fields)
        self.asker = asker


#: A request -> the response's fields.
Handler = Callable[[Request], dict[str, Any]]
#: A first-served request -> what it did (given to its answer, on another thread).
Act = Callable[[Request], Any]
#: What ``Act`` did -> the response's fields.
Answer = Callable[[Any], dict[str, Any]]
#: The longest a reply waits for its client's reader to be matched (seconds).
MATCH_WAIT = 5.0
#: Replies waiting for their client's reader: beyond this the oldest is dropped.
MAX_PENDING = 256
#: How often waiting replies look for their readers (seconds).
RETRY = 0.01


@dataclass(frozen=True)
class _Endpoints:
    """One service's reader of requests and writer of replies, and their message types."""

    request: str
    response: str
    reader: DataReader
    writer: DataWriter


class Services:
    """The node's services: ordinary ones answered in order by one worker, first-served ones on a path each."""

    def __init__(self, node: Node, note: Note) -> None:
        self.node = node
        self.note = note
        self.dropped = 0
        self.replies = Replies(note)
        self._ordinary = Worker("ros2-services", MAX_WAITING, note, self._dropped)
        self._paths: list[tuple[Intake, Worker]] = []

    def serve(self, name: str, service: str, handler: Handler) -> None:
        """Answer ROS service ``name`` (relative to the node: ``list_parameters``) of type ``service``, in turn."""
        ends = self._endpoints(name, service)
        self.node.intake.watch(
            ends.reader, lambda sample: self._queue(lambda: self._answer(ends, sample, handler))
        )

    def _queue(self, job: Callable[[], None]) -> None:
        self._ordinary.put(job)

    def serve_first(self, name: str, service: str, act: Act, answer: Answer) -> None:
        """Serve ``name`` on a path of its own: ``act`` runs as each request is taken, ``answer`` after it."""
        ends = self._endpoints(name, service)
        worker = Worker(f"ros2-{name}", MAX_FIRST, self.note, self._dropped)
        intake = Intake(self.node.participant, f"ros2-{name}-intake", self.note)

        def taken(sample: Any) -> None:
            did = act(self._request(ends, sample))
            worker.put(lambda: self._answer(ends, sample, lambda _: answer(did)))

        intake.watch(ends.reader, taken)
        self._paths.append((intake, worker))

    def _endpoints(self, name: str, service: str) -> _Endpoints:
        full = f"{self.node.fullname}/{name}"
        asked, answer = ros2srv.service_topics(full)
        request, response = ros2srv.request(service), ros2srv.response(service)
        participant = self.node.participant
        reply_topic = Topic(participant, answer, idl.service_type(response))
        writer = DataWriter(participant, reply_topic, qos=dds_qos(SERVICE_QOS, response))
        request_topic = Topic(participant, asked, idl.service_type(request))
        reader = DataReader(participant, request_topic, qos=reader_qos(SERVICE_QOS, request, MAX_WAITING))
        self.node.add_endpoints([reader], [writer])
        return _Endpoints(request, response, reader, writer)

    def _answer(self, ends: _Endpoints, sample: Any, handler: Handler) -> None:
        """Run ``handler`` on a request and hand its reply to ``replies``; a failure costs that request only."""
        try:
            fields = handler(self._request(ends, sample))
            header = (sample.client_guid, sample.sequence_number)
            reply = idl.build_service(ends.response, header, fields)
            self.replies.send(ends.writer, _asker(ends.reader, sample), reply)
        except Exception as exc:
            self.note(f"error answering a {ends.response.rpartition('/')[2]} (ignored): {exc!r}", Level.ERROR)

    def _request(self, ends: _Endpoints, sample: Any) -> Request:
        """``sample``'s fields, and the node that owns the writer it came from."""
        writer = _publication(ends.reader, sample)
        asker = None if writer is None else self.node.graph.node_of(bytes(writer.key.bytes))
        return Request(
            {field.name: getattr(sample, field.name) for field in ros2msg.TYPES[ends.request].fields}, asker
        )

    def _dropped(self) -> None:
        self.dropped += 1

    def close(self) -> None:
        """No request is taken after this; the workers end once they have answered what they hold."""
        for intake, _ in self._paths:
            intake.close()
        deadline = time.monotonic() + CLOSE_WAIT
        for worker in [self._ordinary, *(worker for _, worker in self._paths)]:
            worker.close(deadline)
        self.replies.close(deadline)


@dataclass
class _Reply:
    writer: DataWriter
    asker: Any
    sample: Any
    until: float


class Replies:
    """Replies written once their client's reader is matched, on a thread of their own; none waits in a worker.

    Each reply waits at most ``MATCH_WAIT`` (then it is dropped: its asker is
    gone, or never had a reader); at most ``MAX_PENDING`` wait (a new one
    pushes out the oldest).
    """

    def __init__(self, note: Note) -> None:
        self.written = 0
        self.expired = 0
        self._note = note
        self._pending: deque[_Reply] = deque()
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._closed = False
        #: Each writer's matched readers (instance handle -> participant), learnt once per reader.
        self._readers: dict[int, dict[int, Any]] = {}
        self._thread = threading.Thread(target=self._run, name="ros2-replies", daemon=True)
        self._thread.start()

    def send(self, writer: DataWriter, asker: Any, sample: Any) -> None:
        """Write ``sample`` with ``writer`` once it reaches a reader of participant ``asker`` (None: at once)."""
        with self._lock:
            if len(self._pending) >= MAX_PENDING:
                self._pending.popleft()
                self.expired += 1
            self._pending.append(_Reply(writer, asker, sample, time.monotonic() + MATCH_WAIT))
        self._wake.set()

    def close(self, deadline: float) -> None:
        self._closed = True
        self._wake.set()
        self._thread.join(timeout=max(0.0, deadline - time.monotonic()))

    def _run(self) -> None:
        while not self._closed:
            with self._lock:
                waiting = bool(self._pending)
            self._wake.wait(RETRY if waiting else None)
            self._wake.clear()
            self._try()

    def _try(self) -> None:
        """Write every reply whose reader is there; drop those past their time."""
        with self._lock:
            pending, self._pending = self._pending, deque()
        heard: dict[int, set[Any]] = {}
        now = time.monotonic()
        keep: list[_Reply] = []
        for reply in pending:
            if reply.asker is not None and reply.asker not in self._heard(reply.writer, heard):
                if now < reply.until:
                    keep.append(reply)
                else:
                    self.expired += 1
                continue
            try:
                reply.writer.write(reply.sample)
                self.written += 1
            except Exception as exc:  # a reply that cannot be written costs that reply only
                self._note(f"error writing a reply (ignored): {exc!r}", Level.ERROR)
        with self._lock:
            self._pending.extendleft(reversed(keep))

    def _heard(self, writer: DataWriter, heard: dict[int, set[Any]]) -> set[Any]:
        """The participants ``writer`` reaches a reader of now (looked up once per pass)."""
        key = id(writer)
        if key not in heard:
            known = self._readers.setdefault(key, {})
            handles = set(writer.get_matched_subscriptions())
            for handle in set(known) - handles:
                del known[handle]
            for handle in handles - set(known):
                try:
                    found = writer.get_matched_subscription_data(handle)
                except Exception:  # the reader left while being looked up
                    continue
                if found is not None:
                    known[handle] = found.participant_key
            heard[key] = set(known.values())
        return heard[key]


def _publication(reader: DataReader, sample: Any) -> Any:
    """What discovery said of the writer that sent ``sample``, or None if it is gone already."""
    try:
        return reader.get_matched_publication_data(sample.sample_info.publication_handle)
    except Exception:  # the client left between its request and this answer
        return None


def _asker(reader: DataReader, sample: Any) -> Any:
    """The participant that sent ``sample`` (its key), or None if it is gone already."""
    found = _publication(reader, sample)
    return None if found is None else found.participant_key
