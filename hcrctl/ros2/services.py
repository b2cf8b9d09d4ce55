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

Handlers run on one worker thread of their own, in order, never on Cyclone's
listener thread: a handler may wait for the robot (``stop``), and cmd_vel's
samples must not wait behind it.
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from collections.abc import Callable
from typing import Any

from cyclonedds.core import Listener
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from ..protocol import ros2conv, ros2msg, ros2srv
from . import idl
from .node import Node, Note, dds_qos

#: rmw's default service QoS.
SERVICE_QOS = ros2conv.Qos(reliable=True, transient_local=False, depth=10)
#: A request's fields as a dict -> the response's fields.
Handler = Callable[[dict[str, Any]], dict[str, Any]]
#: The longest a reply waits for its client's reader to be matched (seconds).
MATCH_WAIT = 1.0
#: Requests waiting for the worker: beyond this a burst is dropped (a client retries), never queued forever.
MAX_WAITING = 64


class Services:
    """The node's services: each a request reader and a reply writer, answered in order by one worker."""

    def __init__(self, node: Node, note: Note) -> None:
        self.node = node
        self.note = note
        self.answered = 0
        self.dropped = 0
        self._work: queue.Queue[tuple[Handler, str, str, Any] | None] = queue.Queue(MAX_WAITING)
        self._replies: dict[str, DataWriter] = {}
        self._readers: list[DataReader] = []
        self._index: dict[str, int] = {}
        self._worker = threading.Thread(target=self._run, name="ros2-services", daemon=True)
        self._worker.start()

    def serve(self, name: str, service: str, handler: Handler) -> None:
        """Answer ROS service ``name`` (relative to the node: ``~/stop`` is ``stop``) of type ``service``."""
        full = f"{self.node.fullname}/{name}"
        asked, answer = ros2srv.service_topics(full)
        request, response = ros2srv.request(service), ros2srv.response(service)
        participant = self.node.participant
        reply_topic = Topic(participant, answer, idl.service_type(response))
        writer = DataWriter(participant, reply_topic, qos=dds_qos(SERVICE_QOS, response))
        self._replies[response] = writer
        listener = _Requests(lambda sample: self._queue(handler, request, response, sample), self.note)
        request_topic = Topic(participant, asked, idl.service_type(request))
        qos = dds_qos(SERVICE_QOS, request)
        self._index[request] = len(self._readers)
        self._readers.append(DataReader(participant, request_topic, qos=qos, listener=listener))
        self.node.add_endpoints(self._readers[-1:], [writer])

    def _queue(self, handler: Handler, request: str, response: str, sample: Any) -> None:
        try:
            self._work.put_nowait((handler, request, response, sample))
        except queue.Full:
            self.dropped += 1

    def _run(self) -> None:
        while (job := self._work.get()) is not None:
            handler, request, response, sample = job
            try:
                fields = handler(_fields(request, sample))
                header = (sample.client_guid, sample.sequence_number)
                writer = self._replies[response]
                _until_heard_by(writer, _asker(self._readers[self._index[request]], sample))
                writer.write(idl.build_service(response, header, fields))
                self.answered += 1
            except Exception as exc:  # a request that breaks a handler costs that request only
                self.note(f"error answering a {response.rpartition('/')[2]} (ignored): {exc!r}")

    def close(self) -> None:
        """No request is taken after this; the worker ends once it has answered what it holds."""
        for reader in self._readers:
            reader.set_listener(None)
        self._work.put(None)
        self._worker.join(timeout=5)


def _asker(reader: DataReader, sample: Any) -> Any:
    """The participant that sent ``sample`` (its key), or None if it is gone already."""
    try:
        found = reader.get_matched_publication_data(sample.sample_info.publication_handle)
    except Exception:  # the client left between its request and this answer
        return None
    return None if found is None else found.participant_key


def _until_heard_by(writer: DataWriter, participant: Any) -> None:
    """Wait (at most ``MATCH_WAIT``) until ``writer`` reaches a reader of ``participant``.

    Discovery is two-sided: a client's request may arrive before this node's
    reply writer has learnt the client's reply reader, and a volatile reply
    written then reaches no one (rmw_fastrtps's services wait the same way).
    """
    deadline = time.monotonic() + MATCH_WAIT
    while participant is not None and time.monotonic() < deadline:
        for handle in writer.get_matched_subscriptions():
            with contextlib.suppress(Exception):
                found = writer.get_matched_subscription_data(handle)
                if found is not None and found.participant_key == participant:
                    return
        time.sleep(0.01)


def _fields(request: str, sample: Any) -> dict[str, Any]:
    """A request's own fields (the header left out), nested messages as they are."""
    return {field.name: getattr(sample, field.name) for field in ros2msg.TYPES[request].fields}


class _Requests(Listener):
    """Requests, on Cyclone's listener thread, handed to the worker; a failure costs only its sample."""

    def __init__(self, on_request: Callable[[Any], None], note: Note) -> None:
        super().__init__()
        self._on_request, self._note = on_request, note

    def on_data_available(self, reader: DataReader) -> None:
        try:
            for sample in reader.take(N=64):
                info = getattr(sample, "sample_info", None)
                if info is None or info.valid_data:
                    self._on_request(sample)
        except Exception as exc:  # never into Cyclone's thread
            self._note(f"error reading {reader.topic.name} (ignored): {exc!r}")
