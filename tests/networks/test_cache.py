"""The cache keeps itself whole: damaged entries are made again with a notice, keys depend on
content only, and a killed writer's scratch folder goes."""

import os
import subprocess
import sys

import pytest

from networks.cache import _seal_path, cache_dir, intact, place, scratch_dir, take_notices
from networks.convert import import_opendrive
from networks.towns import town_opendrive
from networks.world import build_world


def test_a_truncated_world_or_net_is_made_again_with_a_notice():
    xodr = town_opendrive("skeleton")
    net = import_opendrive(xodr)
    world = build_world(net)
    take_notices()
    for path in (world.path, net):
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 2])
    net_again = import_opendrive(xodr)
    again = build_world(net_again)
    notices = take_notices()
    assert net_again == net and again.path == world.path
    assert any(str(net) in n and "damaged or incomplete" in n for n in notices)
    assert any(str(world.path) in n for n in notices)
    assert again.mesh.triangles.shape == world.mesh.triangles.shape


def test_the_same_network_converted_in_two_caches_is_the_same_file(tmp_path, monkeypatch):
    xodr = town_opendrive("skeleton")
    nets = []
    for name in ("a", "b"):
        monkeypatch.setenv("SUMO_DATASET_CACHE", str(tmp_path / name))
        nets.append(import_opendrive(xodr))
    assert nets[0].read_bytes() == nets[1].read_bytes()
    assert nets[0].relative_to(tmp_path / "a") == nets[1].relative_to(tmp_path / "b")


def test_a_killed_writers_scratch_folder_is_removed_by_the_next_writer():
    folder = cache_dir("test", "scratch")
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    stale = folder / f".scratch-{int(dead.stdout)}-abc"
    stale.mkdir()
    (stale / "half.xml").write_text("<net")
    with scratch_dir(folder) as scratch:
        assert scratch.name.startswith(f".scratch-{os.getpid()}-")
    assert not stale.exists()


@pytest.mark.parametrize("damage", [b"", b"PK\x03\x04 not a zip"])
def test_a_world_file_that_is_not_a_world_is_one_clear_error(tmp_path, damage):
    from networks.errors import NetworkError
    from networks.world import read_world

    path = tmp_path / "world.npz"
    path.write_bytes(damage)
    with pytest.raises(NetworkError, match="not a readable world file"):
        read_world(path)


def test_a_file_is_placed_after_its_seal_and_a_damaged_one_stays_until_replaced(tmp_path, monkeypatch):
    """Several processes may fill one cache entry: one that looks while another places the file
    must never find the new file without its seal (it would take it for a damaged one), and a
    file found damaged is not deleted under a process that reads it (it is replaced atomically)."""
    path = tmp_path / "entry.bin"
    partial = tmp_path / "entry.partial"
    partial.write_bytes(b"new content")
    seen = []
    real_replace = type(partial).replace

    def watching_replace(self, target):  # what another process would see just before each move
        seen.append((target.name, path.exists(), _seal_path(path).exists()))
        return real_replace(self, target)

    monkeypatch.setattr(type(partial), "replace", watching_replace)
    place(partial, path)
    monkeypatch.undo()
    assert [s for s in seen if s[0] == path.name] == [(path.name, False, True)]  # the seal was there first
    assert intact(path) and path.read_bytes() == b"new content"
    path.write_bytes(b"new cont")  # damaged
    take_notices()
    assert not intact(path) and path.exists()  # made again by the caller, not removed here
    assert len(take_notices()) == 1
