"""Services on the bus: simbot's JSON services (world control), and ROS 2 services as rmw_zenoh serves them.

A JSON service is a queryable whose requests and replies are JSON objects; a ROS 2 service
(`std_srvs/srv/Empty`, `SetBool`, `Trigger`) is a queryable on the service's rmw_zenoh key whose
request is the CDR of `<Service>_Request`, with the client's attachment, and whose reply is the
CDR of `<Service>_Response` with the same sequence number and GID (`simbot.bus.rmw`). Both wait in
a FIFO channel until the simulation loop polls them, and may be answered later from any thread.
"""

from __future__ import annotations

import json
import logging
import threading
from collections.abc import Callable, Mapping
from typing import Any, Protocol

import zenoh

from simbot.bus.codec import DecodeError, decode, encode
from simbot.bus.graph import Announcement, json_token
from simbot.bus.options import zenoh_reason
from simbot.bus.rmw import AttachmentError, Attachments, parse_attachment

logger = logging.getLogger(__name__)

JSON_ENCODING = zenoh.Encoding.APPLICATION_JSON
CDR_ENCODING = zenoh.Encoding.APPLICATION_CDR


class BadRequest(ValueError):
    """A service request whose payload is not a JSON object (or not the service's CDR); str() is one line."""


class ServiceError(RuntimeError):
    """A service answered a call with an error, or with something other than a JSON object."""


class Undeclarable(Protocol):
    def undeclare(self) -> None: ...


def undeclare(entity: Undeclarable | None) -> None:
    """Undeclare a Zenoh entity that may be gone already (its session closed)."""
    if entity is None:
        return
    try:
        entity.undeclare()
    except zenoh.ZError as exc:  # already undeclared, or the session is closed
        logger.debug("undeclare: %s", zenoh_reason(exc))


class Answer:
    """A query answered exactly once, now or later from any thread; then finalised, so that the
    caller's get returns at once rather than at its timeout."""

    def __init__(self, query: zenoh.Query, name: str) -> None:
        self._query = query
        self._name = name
        self._replied = False
        self._lock = threading.Lock()

    def reply_error(self, message: str) -> None:
        """Answer with a Zenoh error reply (`Node.call` raises ServiceError with `message`; a ROS
        client reports the call as failed)."""
        self._finish(lambda: self._query.reply_err(message))

    def _finish(self, send: Callable[[], None]) -> None:
        with self._lock:
            if self._replied:
                raise RuntimeError(f"{self._name}: request already answered")
            self._replied = True
            try:
                send()
            finally:
                self._query.drop()


class Request(Answer):
    """One JSON service request: its payload, and a reply that may come later from any thread."""

    def __init__(self, query: zenoh.Query, key: str) -> None:
        super().__init__(query, key)
        self.key = key
        payload = query.payload
        self.payload = payload.to_bytes() if payload is not None else b""

    def json(self) -> dict[str, Any]:
        """The payload as a JSON object; no payload is `{}`. BadRequest when malformed."""
        if not self.payload.strip():
            return {}
        try:
            value = json.loads(self.payload)
        except (UnicodeDecodeError, ValueError) as exc:
            raise BadRequest(f"{self.key}: malformed JSON: {' '.join(str(exc).split())}") from None
        except RecursionError:
            raise BadRequest(f"{self.key}: JSON nested too deeply") from None
        if not isinstance(value, dict):
            raise BadRequest(f"{self.key}: expected a JSON object, got {type(value).__name__}")
        return value

    def reply(self, obj: Mapping[str, Any]) -> None:
        """Answer with `obj` as JSON and finish the request."""
        text = json.dumps(dict(obj), allow_nan=False)
        self._finish(lambda: self._query.reply(self.key, text, encoding=JSON_ENCODING))


class Queryable:
    """A JSON service on one key; requests wait in a FIFO channel until `poll` takes them."""

    def __init__(self, session: zenoh.Session, key: str, capacity: int) -> None:
        self.key = key
        self._queryable = session.declare_queryable(key, zenoh.handlers.FifoChannel(capacity), complete=True)
        self._announcement = Announcement(session, json_token(key))

    def poll(self) -> list[Request]:
        """The requests that arrived since the last poll, without blocking."""
        requests = []
        while (query := self._queryable.try_recv()) is not None:
            requests.append(Request(query, self.key))
        return requests

    def close(self) -> None:
        """Undeclare the queryable."""
        self._announcement.close()
        undeclare(self._queryable)


class Answering:
    """A queryable that answers `{}` at once on Zenoh's thread (`Node.answering`); off the graph."""

    def __init__(self, session: zenoh.Session, key: str) -> None:
        self._queryable = session.declare_queryable(key, _answer_empty)

    def close(self) -> None:
        undeclare(self._queryable)


def _answer_empty(query: zenoh.Query) -> None:
    with query:
        query.reply(query.key_expr, b"{}", encoding=JSON_ENCODING)


def parse_reply(key: str, data: bytes) -> dict[str, Any]:
    try:
        value = json.loads(data)
    except (UnicodeDecodeError, ValueError):
        raise ServiceError(f"{key}: the reply is not JSON") from None
    if not isinstance(value, dict):
        raise ServiceError(f"{key}: the reply is a JSON {type(value).__name__}, not an object")
    return value


class RosRequest(Answer):
    """One ROS 2 service request: its decoded message, and a reply that may come later from any thread."""

    def __init__(self, query: zenoh.Query, service: RosService) -> None:
        super().__init__(query, service.name)
        self.service = service

    def message(self) -> Any:
        """The request message; BadRequest for a payload that is not the service's request or a
        malformed attachment (the caller answers it with `reply_error`)."""
        try:
            self.attachment()
        except AttachmentError as exc:
            raise BadRequest(f"{self.service.name}: {exc}") from None
        payload = self._query.payload
        try:
            return decode(payload.to_bytes() if payload is not None else b"", self.service.request_type)
        except DecodeError as exc:
            raise BadRequest(f"{self.service.name}: not a {exc}") from None

    def attachment(self) -> bytes:
        """The client's attachment, for the reply's; rmw_zenoh requires one."""
        attachment = self._query.attachment
        if attachment is None:
            raise AttachmentError("a request without rmw_zenoh's attachment")
        data = attachment.to_bytes()
        parse_attachment(data)
        return data

    def reply(self, response: Any) -> None:
        """Answer with `response` (a `<Service>_Response` message) as CDR, with the request's sequence number and GID."""
        data, attachment = encode(response), self.service.attachments.reply(self.attachment())

        def send() -> None:
            self._query.reply(self._query.key_expr, data, encoding=CDR_ENCODING, attachment=attachment)

        self._finish(send)


class RosService:
    """A ROS 2 service (`std_srvs/srv/Trigger`...) on its rmw_zenoh key, on the graph; polled by the loop."""

    def __init__(self, session: zenoh.Session, name: str, key: str, typename: str, token: str, capacity: int) -> None:
        self.name = name
        self.typename = typename
        self.request_type = f"{typename}_Request"
        self.response_type = f"{typename}_Response"
        self.attachments = Attachments()
        self._queryable = session.declare_queryable(key, zenoh.handlers.FifoChannel(capacity), complete=True)
        self._announcement = Announcement(session, token)

    def poll(self) -> list[RosRequest]:
        """The requests that arrived since the last poll, without blocking."""
        requests = []
        while (query := self._queryable.try_recv()) is not None:
            requests.append(RosRequest(query, self))
        return requests

    def close(self) -> None:
        self._announcement.close()
        undeclare(self._queryable)
