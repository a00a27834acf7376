"""The ``assets`` capability: asset_uri_allowlist, package:// resolution, traversal refused."""

from __future__ import annotations

import asyncio
import json
import struct
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.bridge.foxglove import FoxgloveError, FoxgloveOptions, FoxgloveServer
from visnav.bridge.foxglove.assets import (
    DEFAULT_ASSET_URI_ALLOWLIST,
    AssetError,
    AssetResolver,
)
from visnav.bridge.foxglove.protocol import FetchAsset, encode_fetch_asset_response

from .conftest import client, recv_binary

TB3 = Path(__file__).resolve().parents[2] / "data" / "turtlebot3"
BURGER = "package://turtlebot3_description/meshes/bases/burger_base.stl"


@pytest.fixture
def pkg(tmp_path: Path) -> Path:
    """A ROS package ``fx_pkg`` with a mesh, a secret beside it and a ROS_PACKAGE_PATH root."""
    root = tmp_path / "ws" / "fx_pkg"
    (root / "meshes").mkdir(parents=True)
    (root / "package.xml").write_text("<package><name>fx_pkg</name></package>")
    (root / "meshes" / "base.stl").write_bytes(b"solid base\nendsolid base\n")
    (root / "meshes" / "notes.txt").write_text("not an asset type")
    (tmp_path / "secret.stl").write_text("secret")
    return root


def _resolver(pkg: Path, allow: tuple[str, ...] = DEFAULT_ASSET_URI_ALLOWLIST) -> AssetResolver:
    return AssetResolver(allow, env={"ROS_PACKAGE_PATH": str(pkg.parent)})


def test_default_allowlist_is_foxglove_bridges() -> None:
    (pattern,) = DEFAULT_ASSET_URI_ALLOWLIST
    assert pattern == (
        r"^package://(?:[-\w%]+/)*[-\w%.]+\.(?:dae|fbx|glb|gltf|jpeg|jpg|mtl|obj|png|stl|tif|tiff"
        r"|urdf|webp|xacro)$"
    )
    r = AssetResolver()
    assert r.allowed("package://p/meshes/base.STL")  # case ignored, as std::regex::icase
    assert r.allowed("package://p/a.b/m.dae") is False  # '.' only in the file name part
    assert r.allowed("package://p/meshes/v1.2.stl")
    assert not r.allowed("file:///etc/passwd")
    assert not r.allowed("package://p/meshes/run.sh")
    assert not r.allowed("package://p/../../secret.stl")
    assert not r.allowed("package://p/x/\u00e9.stl")  # \w is ASCII, as in ECMAScript


def test_package_uri_resolves_on_ros_package_path(pkg: Path) -> None:
    r = _resolver(pkg)
    assert r.read("package://fx_pkg/meshes/base.stl") == b"solid base\nendsolid base\n"
    with pytest.raises(AssetError, match="matches no asset_uri_allowlist"):
        r.read("package://fx_pkg/meshes/notes.txt")
    with pytest.raises(AssetError, match="no such file"):
        r.read("package://fx_pkg/meshes/missing.stl")
    with pytest.raises(AssetError, match="package 'nope' is not found"):
        r.read("package://nope/meshes/base.stl")


def test_packages_option_and_visnav_itself(pkg: Path) -> None:
    r = AssetResolver(packages={"other": pkg}, env={})
    assert r.read("package://other/meshes/base.stl").startswith(b"solid")
    mesh = AssetResolver(env={"ROS_PACKAGE_PATH": str(TB3)}).read(BURGER)
    assert mesh == (TB3 / "turtlebot3_description/meshes/bases/burger_base.stl").read_bytes()


@pytest.mark.parametrize(
    "uri",
    [
        "package://fx_pkg/../secret.stl",
        "package://fx_pkg/meshes/../../secret.stl",
        "package://fx_pkg/meshes/..%2f..%2fsecret.stl",
        "package://fx_pkg//meshes/base.stl",
        "package://fx_pkg/./meshes/base.stl",
        "package://fx_pkg/meshes\\..\\..\\secret.stl",
        "file://evil.example/etc/passwd.stl",
        "file://../secret.stl",
        "package:///meshes/base.stl",
        "http://127.0.0.1/x.stl",
    ],
)
def test_traversal_and_odd_uris_are_refused(pkg: Path, uri: str) -> None:
    r = _resolver(pkg, (".*",))  # even an allow-everything list
    with pytest.raises(AssetError):
        r.read(uri)


def test_file_uris_only_when_allowed(pkg: Path) -> None:
    mesh = pkg / "meshes" / "base.stl"
    with pytest.raises(AssetError, match="allowlist"):
        _resolver(pkg).read(f"file://{mesh}")
    r = _resolver(pkg, (r"^file://(?:localhost)?/.*\.stl$",))
    assert r.read(f"file://{mesh}").startswith(b"solid")
    assert r.read(f"file://localhost{mesh}").startswith(b"solid")
    small = AssetResolver((".*",), max_bytes=4)
    with pytest.raises(AssetError, match="larger than"):
        small.read(f"file://{mesh}")


def test_bad_allowlist_pattern_is_refused() -> None:
    with pytest.raises(FoxgloveError, match="asset_uri_allowlist"):
        FoxgloveOptions(asset_uri_allowlist=("(",))


_PARTS = st.sampled_from(
    ["..", ".", "", "meshes", "base.stl", "%2e%2e", "..%2f", "\\", "secret.stl", "fx_pkg", "/", "~"]
)


@settings(max_examples=300, deadline=None)
@given(st.lists(_PARTS, min_size=1, max_size=7), st.sampled_from(["package://", "file://", ""]))
def test_fuzzed_uris_never_leave_the_package(
    tmp_path_factory: pytest.TempPathFactory, parts: list[str], scheme: str
) -> None:
    base = tmp_path_factory.getbasetemp() / "fuzz_assets"
    pkg = base / "ws" / "fx_pkg"
    if not pkg.is_dir():
        (pkg / "meshes").mkdir(parents=True)
        (pkg / "package.xml").write_text("<package><name>fx_pkg</name></package>")
        (pkg / "meshes" / "base.stl").write_text("mesh")
        (base / "secret.stl").write_text("secret")
    r = AssetResolver((r"^package://.*",), env={"ROS_PACKAGE_PATH": str(pkg.parent)})
    uri = scheme + "/".join(parts)
    try:
        data = r.read(uri)
    except AssetError:
        return
    assert data == b"mesh"
    assert uri == "package://fx_pkg/meshes/base.stl"


def test_fetch_asset_response_layout() -> None:
    ok = encode_fetch_asset_response(7, data=b"abc")
    assert ok == b"\x04" + struct.pack("<IBI", 7, 0, 0) + b"abc"
    bad = encode_fetch_asset_response(8, error="nope")
    assert bad == b"\x04" + struct.pack("<IBI", 8, 1, 4) + b"nope"


def _fetch(
    server: FoxgloveServer, requests: list[tuple[str, int]]
) -> dict[int, tuple[int, str, bytes]]:
    async def go() -> dict[int, tuple[int, str, bytes]]:
        out: dict[int, tuple[int, str, bytes]] = {}
        async with client(server.url) as ws:
            for uri, rid in requests:
                await ws.send(json.dumps({"op": "fetchAsset", "uri": uri, "requestId": rid}))
            while len(out) < len(requests):
                frame = await recv_binary(ws, 0x04, timeout=10)
                rid, status, n = struct.unpack_from("<IBI", frame, 1)
                out[rid] = (status, frame[10 : 10 + n].decode(), frame[10 + n :])
        return out

    return asyncio.run(go())


def test_server_fetches_a_robot_mesh(
    make_server: Callable[..., FoxgloveServer], pkg: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(TB3))
    server = make_server(packages={"fx_pkg": str(pkg)})
    got = _fetch(
        server,
        [(BURGER, 1), ("package://fx_pkg/../secret.stl", 2), ("file:///etc/passwd", 3),
         ("package://fx_pkg/meshes/base.stl", 4)],
    )  # fmt: skip
    assert got[1] == (
        0,
        "",
        (TB3 / "turtlebot3_description/meshes/bases/burger_base.stl").read_bytes(),
    )
    assert got[2][0] == 1
    assert "'..'" in got[2][1]
    assert got[2][2] == b""
    assert got[3][0] == 1
    assert "allowlist" in got[3][1]
    assert got[4][:2] == (0, "")
    assert got[4][2].startswith(b"solid")


def test_assets_capability_off(make_server: Callable[..., FoxgloveServer]) -> None:
    server = make_server(capabilities=("clientPublish",))

    async def go() -> dict[str, Any]:
        async with client(server.url) as ws:
            await ws.send(json.dumps({"op": "fetchAsset", "uri": BURGER, "requestId": 1}))
            async with asyncio.timeout(5):
                while True:
                    msg = json.loads(s) if isinstance(s := await ws.recv(), str) else {}
                    if msg.get("op") == "status":
                        return msg

    status = asyncio.run(go())
    assert "'assets' capability" in status["message"]


def test_parse_fetch_asset() -> None:
    from visnav.bridge.foxglove import FoxgloveProtocolError, parse_client_message

    msg = parse_client_message(json.dumps({"op": "fetchAsset", "uri": BURGER, "requestId": 5}))
    assert msg == FetchAsset(BURGER, 5)
    with pytest.raises(FoxgloveProtocolError, match="requestId"):
        parse_client_message(json.dumps({"op": "fetchAsset", "uri": BURGER, "requestId": -1}))
    with pytest.raises(FoxgloveProtocolError, match="uri"):
        parse_client_message(json.dumps({"op": "fetchAsset", "requestId": 1}))
