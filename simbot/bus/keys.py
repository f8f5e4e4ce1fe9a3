"""ROS topic names as simbot's keys name them: the fully qualified name without its leading slash.

`/cmd_vel` in namespace `robot1` is `robot1/cmd_vel`. On the wire that name is the middle of
rmw_zenoh's data key, `<domain>/robot1/cmd_vel/<DDS type>/<type hash>` (simbot.bus.rmw), so a ROS 2
node on rmw_zenoh sees the topic as ROS names it; the in-process bus (`local.py`) keys its topics
by the name alone. Characters that Zenoh gives a meaning to (wildcards `*`, `$`, selector syntax
`?`, `#`, verbatim chunks starting with `@`) and empty chunks are refused: a key built from them
would silently match other keys, or none.
"""

from __future__ import annotations

SPECIAL_CHARACTERS = "*$?#"


def _chunks(name: str, what: str, topic: str, namespace: str) -> list[str]:
    """The slash-separated chunks of a topic or namespace, or a ValueError naming the topic."""
    stripped = name.strip("/")
    if not stripped:
        return []
    chunks = stripped.split("/")
    for chunk in chunks:
        reason = None
        if not chunk:
            reason = f"empty chunk ('//') in the {what}"
        elif any(c in SPECIAL_CHARACTERS for c in chunk):
            reason = f"{what} chunk {chunk!r} holds a Zenoh special character (one of {SPECIAL_CHARACTERS})"
        elif chunk.startswith("@"):
            reason = f"{what} chunk {chunk!r} starts with '@' (a Zenoh verbatim chunk)"
        elif chunk != chunk.strip():
            reason = f"{what} chunk {chunk!r} has surrounding whitespace"
        if reason is not None:
            where = f" in namespace {namespace!r}" if namespace else ""
            raise ValueError(f"invalid topic {topic!r}{where}: {reason}")
    return chunks


def topic_key(topic: str, namespace: str = "") -> str:
    """The Zenoh key of a ROS topic: no leading slash, `NAMESPACE/` in front when a namespace is set."""
    topic_chunks = _chunks(topic, "topic", topic, namespace)
    if not topic_chunks:
        raise ValueError(f"invalid topic {topic!r}: empty")
    return "/".join(_chunks(namespace, "namespace", topic, namespace) + topic_chunks)
