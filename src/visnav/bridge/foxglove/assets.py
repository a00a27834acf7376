"""The ``assets`` capability: files a client asks for by URI (``fetchAsset``), as foxglove_bridge.

Foxglove's 3D panel shows a ``robot_description`` whose meshes are ``package://`` URIs by
asking the server for each file. foxglove_bridge answers through ROS's resource_retriever,
for the URIs its ``asset_uri_allowlist`` parameter allows (regular expressions, matched in
full and ignoring case); visnav does the same with its own package lookup:

* ``package://PKG/PATH``: ``PKG`` is found as ``$(find-pkg-share PKG)`` finds it (the
  ``packages`` mapping first, ``visnav`` itself, then ``ROS_PACKAGE_PATH``: a directory
  whose ``package.xml`` names it), and ``PATH`` is a file under it;
* ``file:///ABS/PATH`` (only when the allowlist lets such URIs through: the default does
  not): a file on this machine.

Refused, whatever the allowlist says (as foxglove_bridge does, and more): a URI with two
consecutive dots anywhere (``package://pkg/../../secret``), an empty, ``.`` or
backslash path part, a ``file://`` URI with a host, a path that is not a regular file,
and files larger than :data:`MAX_ASSET_BYTES`. Percent escapes are not decoded (a ``%``
is a character of the file name, so ``%2e%2e`` cannot become ``..``).

Where visnav differs: ``http(s)://`` assets are not fetched (this machine reaches no
network); the error sent back says why (foxglove_bridge sends "Failed to retrieve asset"
and logs the reason).
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

from visnav.bridge.foxglove.errors import FoxgloveError
from visnav.errors import VisnavError
from visnav.launch.substitutions import find_package

__all__ = [
    "DEFAULT_ASSET_URI_ALLOWLIST",
    "MAX_ASSET_BYTES",
    "AssetError",
    "AssetResolver",
    "compile_allowlist",
]

DEFAULT_ASSET_URI_ALLOWLIST = (
    r"^package://(?:[-\w%]+/)*[-\w%.]+\.(?:dae|fbx|glb|gltf|jpeg|jpg|mtl|obj|png|stl|tif|tiff"
    r"|urdf|webp|xacro)$",
)
"""foxglove_bridge's default ``asset_uri_allowlist`` (ROS 2): meshes, textures and robot
descriptions inside ROS packages, nothing else."""

MAX_ASSET_BYTES = 256 << 20
"""Largest asset served (256 MiB): the whole file is sent as one WebSocket frame."""


class AssetError(FoxgloveError):
    """An asset URI that is refused or cannot be read (the message names the URI and why)."""


def compile_allowlist(patterns: Sequence[str]) -> list[re.Pattern[str]]:
    """Compile ``asset_uri_allowlist`` as foxglove_bridge does (ECMAScript-like, ignoring case).

    Word characters are ASCII ones only, as in ECMAScript.

    Raises:
        FoxgloveError: a pattern is not a regular expression (names it).
    """
    out = []
    for p in patterns:
        try:
            out.append(re.compile(p, re.IGNORECASE | re.ASCII))
        except re.error as exc:
            msg = (
                f"asset_uri_allowlist: {p!r} is not a regular expression ({exc}); "
                f"foxglove_bridge's default is {DEFAULT_ASSET_URI_ALLOWLIST[0]!r}"
            )
            raise FoxgloveError(msg) from exc
    return out


class AssetResolver:
    """Resolve and read asset URIs for ``fetchAsset``.

    Args:
        allowlist: ``asset_uri_allowlist`` patterns (full match, ignoring case).
        packages: explicit ``package name -> directory`` (searched before visnav and
            ``ROS_PACKAGE_PATH``).
        env: environment for ``ROS_PACKAGE_PATH`` (default ``os.environ``, read per call).
        max_bytes: largest file served.

    Raises:
        FoxgloveError: a pattern that does not compile.
    """

    def __init__(
        self,
        allowlist: Sequence[str] = DEFAULT_ASSET_URI_ALLOWLIST,
        *,
        packages: Mapping[str, str | os.PathLike[str]] | None = None,
        env: Mapping[str, str] | None = None,
        max_bytes: int = MAX_ASSET_BYTES,
    ) -> None:
        self._allow = compile_allowlist(allowlist)
        self._packages = dict(packages or {})
        self._env = env
        self.max_bytes = max_bytes

    def allowed(self, uri: str) -> bool:
        """Whether ``uri`` passes the allowlist and has no ``..`` (foxglove_bridge's check)."""
        return ".." not in uri and any(p.fullmatch(uri) for p in self._allow)

    def resolve(self, uri: str) -> Path:
        """The file ``uri`` names.

        Raises:
            AssetError: refused (allowlist, ``..``, a bad path part, scheme) or not found.
        """
        if not self.allowed(uri):
            why = "contains '..'" if ".." in uri else "matches no asset_uri_allowlist pattern"
            msg = (
                f"asset {uri!r} refused: it {why} (the server's asset_uri_allowlist decides "
                "which URIs are served; the default serves meshes, textures and URDFs inside "
                "ROS packages)"
            )
            raise AssetError(msg)
        if "\x00" in uri or "\\" in uri:
            msg = f"asset {uri!r} refused: NUL or backslash in the URI"
            raise AssetError(msg)
        if uri.startswith("package://"):
            return self._package_file(uri)
        if uri.startswith("file://"):
            rest = uri[len("file://") :]
            if rest.startswith("localhost/"):
                rest = rest[len("localhost") :]
            if not rest.startswith("/"):
                msg = f"asset {uri!r} refused: a file URI is file:///absolute/path (no host)"
                raise AssetError(msg)
            _check_parts(uri, rest.lstrip("/"))
            return _regular_file(uri, Path(rest))
        scheme = uri.partition(":")[0] if ":" in uri else "(none)"
        msg = (
            f"asset {uri!r}: scheme {scheme!r} is not served; visnav serves package:// and "
            "file:// assets"
        )
        raise AssetError(msg)

    def read(self, uri: str) -> bytes:
        """The bytes of the file ``uri`` names.

        Raises:
            AssetError: as :meth:`resolve`, a file over ``max_bytes``, or a read error.
        """
        path = self.resolve(uri)
        try:
            size = path.stat().st_size
            if size > self.max_bytes:
                msg = f"asset {uri!r} is {size} bytes: larger than the {self.max_bytes} served"
                raise AssetError(msg)
            return path.read_bytes()
        except OSError as exc:
            msg = f"asset {uri!r} cannot be read ({exc.strerror or exc})"
            raise AssetError(msg) from exc

    def _package_file(self, uri: str) -> Path:
        package, _, rel = uri[len("package://") :].partition("/")
        if not package or not rel:
            msg = f"asset {uri!r} refused: expected package://PACKAGE/PATH/TO/FILE"
            raise AssetError(msg)
        _check_parts(uri, rel)
        try:
            root = Path(find_package(package, packages=self._packages, env=self._env))
        except VisnavError as exc:
            msg = (
                f"asset {uri!r}: package {package!r} is not found on this server "
                "(ROS_PACKAGE_PATH of the server, or its packages option)"
            )
            raise AssetError(msg) from exc
        return _regular_file(uri, root / rel)


def _check_parts(uri: str, rel: str) -> None:
    for part in rel.split("/"):
        if part in ("", ".", ".."):
            msg = f"asset {uri!r} refused: an empty, '.' or '..' path part"
            raise AssetError(msg)


def _regular_file(uri: str, path: Path) -> Path:
    if not path.is_file():
        msg = f"asset {uri!r}: no such file on this server"
        raise AssetError(msg)
    return path
