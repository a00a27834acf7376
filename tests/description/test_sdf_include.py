"""SDF ``<include>`` and ``model://`` resolved as Gazebo Classic does; meshes, colours, errors."""

from __future__ import annotations

import contextlib
import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from visnav.description.errors import WorldError, WorldWarning
from visnav.description.gazebo_materials import GAZEBO_COLOURS, read_material_scripts
from visnav.description.mesh_files import load_mesh
from visnav.description.model_path import ModelPath, model_path, model_sdf_file
from visnav.description.sdf_world import parse_sdf_world
from visnav.description.world import load_world
from visnav.description.worldmodel import Box, Cylinder, Mesh
from visnav.errors import VisnavError

DATA = Path(__file__).resolve().parent.parent / "data"
TB3_GAZEBO = DATA / "turtlebot3" / "turtlebot3_gazebo"
GAZEBO_MODELS = DATA / "gazebo_models"

COLLADA = """<?xml version="1.0"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
 <asset><unit name="cm" meter="{meter}"/><up_axis>Y_UP</up_axis></asset>
 <library_images><image id="img"><init_from>{texture}</init_from></image></library_images>
 <library_effects>
  <effect id="red-fx"><profile_COMMON><technique sid="t"><lambert>
   <diffuse><color>0.8 0.1 0.1 1</color></diffuse></lambert></technique></profile_COMMON></effect>
  <effect id="tex-fx"><profile_COMMON>
   <newparam sid="surf"><surface type="2D"><init_from>img</init_from></surface></newparam>
   <newparam sid="samp"><sampler2D><source>surf</source></sampler2D></newparam>
   <technique sid="t"><lambert><diffuse><texture texture="samp" texcoord="UV"/></diffuse>
   </lambert></technique></profile_COMMON></effect>
 </library_effects>
 <library_materials>
  <material id="red"><instance_effect url="#red-fx"/></material>
  <material id="tex"><instance_effect url="#tex-fx"/></material>
 </library_materials>
 <library_geometries><geometry id="cube"><mesh>
  <source id="pos"><float_array id="pa" count="24">0 0 0 100 0 0 100 100 0 0 100 0 0 0 100
   100 0 100 100 100 100 0 100 100</float_array><technique_common>
   <accessor source="#pa" count="8" stride="3"><param name="X" type="float"/>
   <param name="Y" type="float"/><param name="Z" type="float"/></accessor></technique_common>
  </source>
  <vertices id="v"><input semantic="POSITION" source="#pos"/></vertices>
  <triangles material="m1" count="6"><input semantic="VERTEX" source="#v" offset="0"/>
   <p>0 2 1 0 3 2 4 5 6 4 6 7 0 1 5 0 5 4</p></triangles>
  <triangles material="m2" count="6"><input semantic="VERTEX" source="#v" offset="0"/>
   <p>2 3 7 2 7 6 1 2 6 1 6 5 3 0 4 3 4 7</p></triangles>
 </mesh></geometry></library_geometries>
 <library_visual_scenes><visual_scene id="s"><node id="n"><translate>{tx} 0 0</translate>
  <instance_geometry url="#cube"><bind_material><technique_common>
   <instance_material symbol="m1" target="#red"/><instance_material symbol="m2" target="#tex"/>
  </technique_common></bind_material></instance_geometry></node></visual_scene>
 </library_visual_scenes>
 <scene><instance_visual_scene url="#s"/></scene>
</COLLADA>
"""


def collada(
    path: Path, *, meter: float = 0.01, texture: str = "missing.png", tx: float = 0
) -> Path:
    """A 1 m cube (100 units of ``meter``) shifted ``tx`` units: red faces and textured faces."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(COLLADA.format(meter=meter, texture=texture, tx=tx))
    return path


def model(
    root: Path,
    name: str,
    body: str,
    *,
    config: str | None = None,
    sdf_name: str = "model.sdf",
) -> Path:
    """A model directory ``root/name`` with ``body`` inside ``<sdf><model name=name>``."""
    directory = root / name
    directory.mkdir(parents=True, exist_ok=True)
    (directory / sdf_name).write_text(
        f'<?xml version="1.0"?><sdf version="1.6"><model name="{name}">{body}</model></sdf>'
    )
    if config is not None:
        (directory / "model.config").write_text(config)
    return directory


BOX_LINK = (
    "<static>true</static><link name='l'><collision name='c'><geometry><box><size>{s} {s} {s}"
    "</size></box></geometry></collision></link>"
)


def world(body: str) -> str:
    return f'<sdf version="1.6"><world name="w">{body}</world></sdf>'


def include(uri: str, extra: str = "") -> str:
    return f"<include><uri>{uri}</uri>{extra}</include>"


def parse(text: str, roots: list[Path], **kwargs: object) -> object:
    path = ModelPath(roots=tuple(roots), origins=tuple("test" for _ in roots))
    return parse_sdf_world(text, model_path=path, **kwargs)  # type: ignore[arg-type]


# --------------------------------------------------------------------- resolution


def test_model_path_order_gazebo_model_path_then_package_exports_then_cache(
    tmp_path: Path,
) -> None:
    first, second, cache = tmp_path / "first", tmp_path / "second", tmp_path / "home"
    pkg = tmp_path / "my_pkg"
    (pkg / "models").mkdir(parents=True)
    (pkg / "package.xml").write_text(
        "<package><name>my_pkg</name><export>"
        '<gazebo_ros gazebo_model_path="${prefix}/models"/>'
        '<gazebo_ros gazebo_media_path="${prefix}"/></export></package>'
    )
    for root in (first, second, cache / ".gazebo" / "models"):
        model(root, "thing", BOX_LINK.format(s=1))
    model(second, "only_second", BOX_LINK.format(s=1))
    model(pkg / "models", "from_pkg", BOX_LINK.format(s=1))
    model(cache / ".gazebo" / "models", "cached", BOX_LINK.format(s=1))
    env = {"GAZEBO_MODEL_PATH": f"{first}:{second}:{tmp_path / 'nope'}"}
    path = model_path(packages={"my_pkg": pkg}, environ=env, home=cache)
    assert path.roots == (first, second, pkg / "models", cache / ".gazebo" / "models")
    assert path.origins[:3] == ("GAZEBO_MODEL_PATH", "GAZEBO_MODEL_PATH", "package my_pkg")
    assert path.find("thing") == first / "thing"
    assert path.find("only_second") == second / "only_second"
    assert path.find("from_pkg") == pkg / "models" / "from_pkg"
    assert path.find("cached") == cache / ".gazebo" / "models" / "cached"
    assert path.find("absent") is None
    assert path.find("../first") is None
    assert pkg in path.resources
    # ROS_PACKAGE_PATH is crawled for packages (rospack stops at a package.xml)
    crawled = model_path(environ={"ROS_PACKAGE_PATH": str(tmp_path)}, home=tmp_path / "none")
    assert crawled.roots == (pkg / "models",)


def test_world_file_package_exports_its_models() -> None:
    path = model_path(
        world_file=TB3_GAZEBO / "worlds" / "turtlebot3_world.world",
        environ={},
        home=TB3_GAZEBO,
    )
    assert path.roots == ((TB3_GAZEBO / "models").resolve(),)


def test_model_config_picks_the_sdf_gazebo_would(tmp_path: Path) -> None:
    config = (
        "<model><name>m</name><sdf version='1.4'>old.sdf</sdf><sdf version='1.6'>mid.sdf</sdf>"
        "<sdf version='1.10'>new.sdf</sdf></model>"
    )
    directory = model(tmp_path, "m", "", config=config, sdf_name="mid.sdf")
    for name in ("old.sdf", "new.sdf"):
        (directory / name).write_text("<sdf/>")
    assert model_sdf_file(directory) == directory / "mid.sdf"  # 1.10 > 1.7: too new
    only_new = model(tmp_path, "n", "", config="<model><sdf version='2.0'>a.sdf</sdf></model>")
    (only_new / "a.sdf").write_text("<sdf/>")
    assert model_sdf_file(only_new) == only_new / "a.sdf"
    plain = model(tmp_path, "plain", "")
    assert model_sdf_file(plain) == plain / "model.sdf"
    broken = model(tmp_path, "broken", "", config="<model><sdf")
    with pytest.raises(WorldError, match=r"malformed or unreadable model\.config"):
        model_sdf_file(broken)
    wrong = model(tmp_path, "wrong", "", config="<model><sdf version='1.5'>x.sdf</sdf></model>")
    with pytest.raises(WorldError, match=r"its SDF file 'x\.sdf' does not exist"):
        model_sdf_file(wrong)


def test_include_name_pose_static_and_nesting(tmp_path: Path) -> None:
    root = tmp_path / "models"
    model(root, "crate", "<pose>5 5 5 0 0 0</pose>" + BOX_LINK.format(s=0.5))
    model(
        root,
        "pair",
        "<static>true</static><pose>0 0 1 0 0 0</pose>"
        + include("model://crate", "<name>left</name><pose>0 1 0 0 0 0</pose>")
        + "<model name='inner'><pose>0 -1 0 0 0 0</pose>"
        + BOX_LINK.format(s=0.25)
        + "</model>",
    )
    text = world(
        include("model://crate", "<name>a</name><pose>1 2 0 0 0 1.5707963</pose>")
        + include("model://crate", "<name>b</name><static>false</static>")
        + include("model://pair", "<pose>10 0 0 0 0 1.5707963</pose>")
    )
    with pytest.warns(WorldWarning, match="'b' is not static"):
        out = parse(text, [root])
    a = out.shape("a/l/c")  # type: ignore[attr-defined]
    assert isinstance(a, Box)
    np.testing.assert_allclose(a.pos, (1, 2, 0), atol=1e-9)  # the include's pose replaces it
    assert a.rpy[2] == pytest.approx(math.pi / 2)
    np.testing.assert_allclose(out.shape("b/l/c").pos, (5, 5, 5))  # type: ignore[attr-defined]
    left = out.shape("pair::left/l/c")  # type: ignore[attr-defined]
    # the outer include's pose replaced pair's own (0 0 1), then composes with the nested one
    np.testing.assert_allclose(left.pos, (9, 0, 0), atol=1e-7)
    inner = out.shape("pair::inner/l/c")  # type: ignore[attr-defined]
    np.testing.assert_allclose(inner.pos, (11, 0, 0), atol=1e-7)


def test_include_cycles_are_one_error(tmp_path: Path) -> None:
    model(tmp_path, "loop", "<static>1</static>" + include("model://loop"))
    with pytest.raises(WorldError, match="nests 16 levels deep"):
        parse(world(include("model://loop")), [tmp_path])


# --------------------------------------------------------------------- missing models


def test_missing_models_are_one_error_listing_all_and_skip_loads_the_rest(
    tmp_path: Path,
) -> None:
    model(tmp_path, "here", BOX_LINK.format(s=1))
    mesh_model = (
        "<static>1</static><link name='l'><visual name='v'><geometry><mesh>"
        "<uri>model://gone_mesh/meshes/x.dae</uri></mesh></geometry></visual></link>"
    )
    text = world(
        include("model://here")
        + include("model://cafe_table")
        + include("model://mailbox")
        + include("model://cafe_table", "<name>again</name>")
        + f"<model name='m'>{mesh_model}</model>"
        + include("model://ground_plane")
        + include("model://sun")
    )
    with pytest.raises(WorldError) as info:
        parse(text, [tmp_path], source="house.world")
    message = str(info.value)
    assert message.startswith("house.world: 3 model(s) not found: model://cafe_table")
    for name in ("model://mailbox", "model://gone_mesh"):
        assert name in message
    for fix in ("GAZEBO_MODEL_PATH", "--package", "skip_missing_models", str(tmp_path)):
        assert fix in message
    assert "\n" not in message
    with pytest.warns(WorldWarning) as caught:
        out = parse(text, [tmp_path], source="house.world", skip_missing_models=True)
    missing = [str(w.message) for w in caught if "not found" in str(w.message)]
    assert len(missing) == 1
    assert [s.name for s in out.shapes] == ["here/l/c"]  # type: ignore[attr-defined]
    assert out.ground is not None  # type: ignore[attr-defined]
    assert len(out.lights) == 1  # type: ignore[attr-defined]


def test_ground_plane_and_sun_from_the_model_path_win_over_the_built_in(tmp_path: Path) -> None:
    model(
        tmp_path,
        "ground_plane",
        "<static>true</static><link name='link'><collision name='c'><geometry><plane>"
        "<normal>0 0 1</normal><size>7 9</size></plane></geometry></collision></link>",
    )
    (tmp_path / "sun").mkdir()
    (tmp_path / "sun" / "model.sdf").write_text(
        "<sdf version='1.6'><light type='directional' name='sun'>"
        "<direction>0 0 -1</direction></light></sdf>"
    )
    out = parse(world(include("model://ground_plane") + include("model://sun")), [tmp_path])
    assert out.ground.size == (7.0, 9.0)  # type: ignore[attr-defined]
    assert [(li.name, li.dir) for li in out.lights] == [("sun", (0.0, 0.0, -1.0))]  # type: ignore[attr-defined]


# --------------------------------------------------------------------- meshes and colours


def test_collada_units_node_transforms_scale_and_colours(tmp_path: Path) -> None:
    dae = collada(tmp_path / "m" / "meshes" / "cube.dae", meter=0.01, tx=50)
    with pytest.warns(WorldWarning, match="texture 'missing.png' not found") as caught:
        out = parse(
            world(
                "<model name='m'><static>1</static><link name='l'>"
                "<visual name='v'><geometry><mesh><uri>model://m/meshes/cube.dae</uri>"
                "<scale>2 1 0.5</scale></mesh></geometry></visual>"
                "<visual name='grey'><pose>0 5 0 0 0 0</pose><geometry><mesh>"
                f"<uri>file://{dae}</uri></mesh></geometry><material><script>"
                "<uri>file://media/materials/scripts/gazebo.material</uri>"
                "<name>Gazebo/Grey</name></script></material></visual>"
                "<visual name='slashes'><pose>0 9 0 0 0 0</pose><geometry><mesh>"
                "<uri>model:///m/meshes/cube.dae</uri></mesh></geometry></visual>"
                "</link></model>"
            ),
            [tmp_path],
        )
    assert sum("texture" in str(w.message) for w in caught) == 1  # once per file
    mesh = out.shape("m/l/v")  # type: ignore[attr-defined]
    assert isinstance(mesh, Mesh)
    # <unit meter=0.01>: 100 units = 1 m; the node's translate 50 units; then <scale>
    np.testing.assert_allclose(mesh.bounds, ((1.0, 0.0, 0.0), (3.0, 1.0, 0.5)))
    assert mesh.rgba is None  # no SDF material: the file's colours
    assert [p.rgba for p in mesh.parts] == [(0.8, 0.1, 0.1, 1.0), None]
    grey = out.shape("m/l/grey")  # type: ignore[attr-defined]
    assert grey.rgba == GAZEBO_COLOURS["Gazebo/Grey"] == (0.7, 0.7, 0.7, 1.0)
    slashes = out.shape("m/l/slashes")  # type: ignore[attr-defined]
    np.testing.assert_allclose(slashes.bounds, ((0.5, 0, 0), (1.5, 1, 1)))


def test_texture_is_its_mean_colour(tmp_path: Path) -> None:
    from PIL import Image

    textures = tmp_path / "materials" / "textures"
    textures.mkdir(parents=True)
    Image.fromarray(np.full((4, 4, 3), (0, 128, 255), np.uint8)).save(textures / "blue.png")
    # Gazebo looks for a Collada texture in ../materials/textures too
    mesh = load_mesh(collada(tmp_path / "meshes" / "c.dae", texture="blue.png"))
    assert mesh.warnings == ()
    assert mesh.parts[1].rgba == pytest.approx((0.0, 128 / 255, 1.0, 1.0))


def test_material_scripts_of_a_model(tmp_path: Path) -> None:
    from PIL import Image

    scripts = tmp_path / "m" / "materials" / "scripts"
    scripts.mkdir(parents=True)
    textures = tmp_path / "m" / "materials" / "textures"
    textures.mkdir(parents=True)
    Image.fromarray(np.full((2, 2, 3), (200, 100, 0), np.uint8)).save(textures / "t.png")
    (scripts / "a.material").write_text(
        "// comment\nmaterial My/Plain\n{\n technique\n {\n  pass\n  {\n"
        "   ambient 0.1 0.1 0.1\n   diffuse 0.2 0.4 0.6 1.0\n  }\n }\n}\n"
        "material My/Textured { technique { pass { diffuse 0.5 1 1\n"
        " texture_unit { texture t.png } } } }\n"
        "material My/Child : My/Plain\n{\n}\n"
        "/* material My/Commented { technique { pass { diffuse 1 0 0 } } } */\n"
        "material My/Missing { technique { pass { texture_unit { texture nope.png } } } }\n"
    )
    read = read_material_scripts([scripts])
    assert read.colours["My/Plain"] == pytest.approx((0.2, 0.4, 0.6, 1.0))
    assert read.colours["My/Textured"] == pytest.approx((0.5 * 200 / 255, 100 / 255, 0.0, 1.0))
    assert read.colours["My/Child"] == pytest.approx((0.2, 0.4, 0.6, 1.0))
    assert "My/Commented" not in read.colours
    assert read.colours["My/Missing"] == (1.0, 1.0, 1.0, 1.0)
    assert len(read.warnings) == 1
    assert "nope.png" in read.warnings[0]
    body = (
        "<static>1</static><link name='l'><visual name='v'><geometry><box><size>1 1 1</size>"
        "</box></geometry><material><script><uri>model://m/materials/scripts</uri>"
        "<uri>model://m/materials/textures</uri><name>My/Textured</name></script></material>"
        "</visual></link>"
    )
    model(tmp_path, "m", body)
    out = parse(world(include("model://m")), [tmp_path])
    assert out.shape("m/l/v").rgba == pytest.approx(read.colours["My/Textured"])  # type: ignore[attr-defined]


def test_empty_tags_are_warnings_with_sdf_defaults() -> None:
    text = world(
        "<model name='m'><static></static><pose></pose><link name='l'><collision name='c'>"
        "<geometry><box><size></size></box></geometry></collision>"
        "<collision name='k'><pose>3 0 0 0 0 0</pose><geometry><cylinder><radius/>"
        "<length>2</length></cylinder></geometry></collision></link></model>"
    )
    with pytest.warns(WorldWarning, match="empty; SDF's default"):
        out = parse(text, [])
    box = out.shape("m/l/c")  # type: ignore[attr-defined]
    assert isinstance(box, Box)
    assert box.size == (1.0, 1.0, 1.0)
    cylinder = out.shape("m/l/k")  # type: ignore[attr-defined]
    assert isinstance(cylinder, Cylinder)
    assert cylinder.radius == 0.5


# --------------------------------------------------------------------- fixtures


def test_turtlebot3_world_has_every_obstacle(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("GAZEBO_MODEL_PATH", "")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", WorldWarning)
        out = load_world(TB3_GAZEBO / "worlds" / "turtlebot3_world.world")
    cylinders = [s for s in out.shapes if isinstance(s, Cylinder)]
    meshes = {s.name.rsplit("/", 1)[-1]: s for s in out.shapes if isinstance(s, Mesh)}
    assert len(cylinders) == 9
    assert all(c.collision and c.visual and c.radius == 0.15 for c in cylinders)
    assert sorted(meshes) == ["body", "head", "left_foot", "left_hand", "right_foot", "right_hand"]
    # hexagon.dae: inch units (0.0254), circumradius 57.735 in, 100 in high, times <scale>
    head = meshes["head"]
    assert head.bounds[1] == pytest.approx(
        (57.735 * 0.0254 * 0.8, 50 * 0.0254 * 0.8, 2.032), rel=1e-4
    )
    assert head.rgba == GAZEBO_COLOURS["Gazebo/Green"]
    wall = meshes["body"]
    assert wall.rgba == GAZEBO_COLOURS["Gazebo/FlatBlack"]
    assert wall.bounds[1] == pytest.approx((450 * 0.00635, 519.615 * 0.00635, 1.27), rel=1e-4)


def test_turtlebot3_house_loads_with_the_vendored_models(monkeypatch: pytest.MonkeyPatch) -> None:
    house = TB3_GAZEBO / "worlds" / "turtlebot3_house.world"
    monkeypatch.setenv("GAZEBO_MODEL_PATH", str(GAZEBO_MODELS))
    monkeypatch.setenv("HOME", str(GAZEBO_MODELS / "nowhere"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", WorldWarning)
        out = load_world(house)
    names = {s.name for s in out.shapes if isinstance(s, Mesh)}
    assert names == {
        f"turtlebot3_house::{m}/link/visual"
        for m in (
            "Mailbox",
            "cafe_table",
            "cafe_table_0",
            "first_2015_trash_can",
            "first_2015_trash_can_0",
            "table_marble",
        )
    }
    assert len(out.shapes) == 111
    mailbox = out.shape("turtlebot3_house::Mailbox/link/visual")
    assert mailbox.rgba is not None  # Mailbox/Diffuse: the mean colour of its texture
    assert mailbox.collision
    can = out.shape("turtlebot3_house::first_2015_trash_can/link/visual")
    assert isinstance(can, Mesh)
    assert can.rgba is None
    assert can.parts[0].rgba == pytest.approx((0.0216, 0.2488, 0.0064, 1.0))
    # without the models: one error naming the four, and how to add them
    monkeypatch.setenv("GAZEBO_MODEL_PATH", "")
    with pytest.raises(WorldError, match="4 model") as info:
        load_world(house)
    for name in ("cafe_table", "first_2015_trash_can", "mailbox", "table_marble"):
        assert f"model://{name}" in str(info.value)


# --------------------------------------------------------------------- fuzz

_PIECES = [
    "<include>",
    "</include>",
    "<uri>model://m</uri>",
    "<uri>model://</uri>",
    "<uri>model:///m/x</uri>",
    "<uri>file://../m</uri>",
    "<uri>http://x/y</uri>",
    "<name>n</name>",
    "<pose>1 2 3 0 0 0</pose>",
    "<pose>a</pose>",
    "<pose/>",
    "<static>maybe</static>",
    "<static/>",
    "<model name='q'>",
    "</model>",
    "<link name='l'>",
    "</link>",
]
_CONFIG = [
    "<model>",
    "</model>",
    "<sdf version='1.6'>model.sdf</sdf>",
    "<sdf version='x'>model.sdf</sdf>",
    "<sdf version='1.5'>../m/model.sdf</sdf>",
    "<sdf>nothing.sdf</sdf>",
    "<sdf version='1.4'/>",
    "<name>m</name>",
]


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    body=st.lists(st.sampled_from(_PIECES), max_size=10).map("".join),
    config=st.lists(st.sampled_from(_CONFIG), max_size=6).map("".join),
    model_body=st.lists(st.sampled_from(_PIECES), max_size=6).map("".join),
    skip=st.booleans(),
)
def test_fuzz_include_and_model_config_only_visnav_errors_escape(
    tmp_path_factory: pytest.TempPathFactory, body: str, config: str, model_body: str, skip: bool
) -> None:
    root = tmp_path_factory.mktemp("fuzz")
    directory = root / "m"
    directory.mkdir()
    (directory / "model.config").write_text(config)
    (directory / "model.sdf").write_text(
        f"<sdf version='1.6'><model name='m'>{model_body}</model></sdf>"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", WorldWarning)
        with contextlib.suppress(VisnavError):
            parse(world(body), [root], skip_missing_models=skip)


@pytest.mark.parametrize(
    ("package", "world_file", "vendored", "missing"),
    [
        (
            "aws_robomaker_small_house_world",
            "small_house.world",
            ("FloorB_01", "HouseWallB_01", "NightStand_01", "Trash_01"),
            59,
        ),
        (
            "aws_robomaker_bookstore_world",
            "bookstore.world",
            ("RetailShopFloor_01", "RetailShopWall_01", "Holder_01", "MagicCube_01"),
            22,
        ),
    ],
)
def test_aws_worlds_load_what_is_vendored(
    monkeypatch: pytest.MonkeyPatch,
    package: str,
    world_file: str,
    vendored: tuple[str, ...],
    missing: int,
) -> None:
    """Worlds of <model name=X><include>...</include><pose/></model>; the package exports
    its models; the floor is a mesh (no ground_plane); relative file:// URIs."""
    monkeypatch.setenv("GAZEBO_MODEL_PATH", "")
    monkeypatch.setenv("ROS_PACKAGE_PATH", "")
    monkeypatch.setenv("HOME", str(DATA / package / "nowhere"))
    path = DATA / package / "worlds" / world_file
    with pytest.raises(WorldError, match=f"{missing} model\\(s\\) not found"):
        load_world(path)
    out = load_world(path, skip_missing_models=True)  # logs its warnings as one block
    assert sum("not found" in w for w in out.warnings) == 1
    assert out.ground is None
    meshes = [s for s in out.shapes if isinstance(s, Mesh)]
    assert len(meshes) == len(out.shapes)
    found = {s.name.split("::")[1].split("/")[0].rsplit("_", 2)[-2] for s in meshes}
    assert {v.rsplit("_", 1)[0] for v in vendored} == found
    floor = next(s for s in meshes if "Floor" in s.name and s.collision)
    assert floor.bounds[1][2] - floor.bounds[0][2] < 0.5  # a slab
    assert all(s.rgba is None and s.parts for s in meshes)  # the files' own colours
