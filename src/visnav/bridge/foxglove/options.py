"""The Foxglove server's options (foxglove_bridge's parameters) and their checks."""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from visnav.bridge.foxglove.assets import DEFAULT_ASSET_URI_ALLOWLIST, compile_allowlist
from visnav.bridge.foxglove.errors import FoxgloveError
from visnav.bridge.foxglove.protocol import CAPABILITIES

__all__ = ["FoxgloveOptions", "compile_patterns", "matches"]


@dataclass(frozen=True)
class FoxgloveOptions:
    """What the server serves (foxglove_bridge's parameter names, lists as tuples).

    Attributes:
        address: address to bind; ``127.0.0.1`` (this machine only) unless asked.
        port: TCP port (foxglove_bridge's 8765; 0: any free port).
        topic_whitelist: regular expressions (full match) of topics advertised.
        service_whitelist: ... of services advertised.
        param_whitelist: ... of ``<node>.<param>`` names served.
        client_topic_whitelist: ... of topics clients may publish on.
        send_buffer_limit: per-client bytes queued before message data is dropped.
        capabilities: offered capabilities (``time`` only counts with sim time).
        include_hidden: also advertise hidden topics and services (a ``_`` name part).
        min_qos_depth: least depth of a subscription made for a client.
        max_qos_depth: largest depth (the publishers' depths are summed, then clamped).
        use_compression: offer permessage-deflate (off: images cost CPU to compress).
        service_timeout_s: timeout of a service call made for a client.
        name: the server name clients show.
        asset_uri_allowlist: regular expressions (full match, ignoring case) of the asset
            URIs served to ``fetchAsset`` (foxglove_bridge's default: files of meshes,
            textures and URDFs inside ROS packages).
        packages: ``package name -> directory`` for ``package://`` assets, searched
            before visnav's own and ``ROS_PACKAGE_PATH``.
    """

    address: str = "127.0.0.1"
    port: int = 8765
    topic_whitelist: tuple[str, ...] = (".*",)
    service_whitelist: tuple[str, ...] = (".*",)
    param_whitelist: tuple[str, ...] = (".*",)
    client_topic_whitelist: tuple[str, ...] = (".*",)
    send_buffer_limit: int = 10_000_000
    capabilities: tuple[str, ...] = CAPABILITIES
    include_hidden: bool = False
    min_qos_depth: int = 1
    max_qos_depth: int = 25
    use_compression: bool = False
    service_timeout_s: float = 5.0
    name: str = "visnav"
    asset_uri_allowlist: tuple[str, ...] = DEFAULT_ASSET_URI_ALLOWLIST
    packages: Mapping[str, str] = field(default_factory=dict, hash=False)

    def __post_init__(self) -> None:
        for key in ("topic_whitelist", "service_whitelist", "param_whitelist"):
            compile_patterns(key, getattr(self, key))
        compile_patterns("client_topic_whitelist", self.client_topic_whitelist)
        compile_allowlist(self.asset_uri_allowlist)
        unknown = sorted(set(self.capabilities) - set(CAPABILITIES))
        if unknown:
            msg = (
                f"capabilities {unknown}: not served by visnav's Foxglove server; "
                f"expected some of {list(CAPABILITIES)}"
            )
            raise FoxgloveError(msg)
        if self.send_buffer_limit < 1:
            msg = f"send_buffer_limit is {self.send_buffer_limit}: expected a positive byte count"
            raise FoxgloveError(msg)
        if not 0 <= self.port <= 65535:
            msg = f"port is {self.port}: expected 0..65535 (0: any free port)"
            raise FoxgloveError(msg)
        if not 1 <= self.min_qos_depth <= self.max_qos_depth:
            msg = (
                f"min_qos_depth {self.min_qos_depth} / max_qos_depth {self.max_qos_depth}: "
                "expected 1 <= min <= max"
            )
            raise FoxgloveError(msg)


def compile_patterns(key: str, patterns: Sequence[str]) -> list[re.Pattern[str]]:
    """Compile a whitelist.

    Raises:
        FoxgloveError: a pattern is not a regular expression (names the option).
    """
    out = []
    for p in patterns:
        try:
            out.append(re.compile(p))
        except re.error as exc:
            msg = f"{key}: {p!r} is not a regular expression ({exc}); e.g. '/camera/.*'"
            raise FoxgloveError(msg) from exc
    return out


def matches(patterns: list[re.Pattern[str]], name: str) -> bool:
    """Whether ``name`` matches one of the patterns in full."""
    return any(p.fullmatch(name) for p in patterns)
