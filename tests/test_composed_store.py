"""Compositions kept on disk (schema/composed_store.py): a later process reads them instead of running Hydra, and
any change to what a composition was made from composes again."""

from __future__ import annotations

import shutil

import pytest

from envfactory.geometry.kernels import native
from envfactory.schema import compose, composed_store
from envfactory.schema.compose import FamilyFile, load_env_spec
from envfactory.schema.errors import SpecError
from envfactory.schema.folders import builtin_root


@pytest.fixture
def family(tmp_path, monkeypatch):
    """The shipped UR5e Reach family, copied into a folder of its own that searches the built-in robots and tasks;
    a store of its own; nothing composed in this process yet."""
    monkeypatch.setenv("ENVFACTORY_CACHE_DIR", str(tmp_path / "cache"))
    (tmp_path / "specs").mkdir()
    path = tmp_path / "specs" / "myreach.yaml"
    shutil.copy(builtin_root() / "specs" / "ur5e_reach.yaml", path)
    compose._compose_cached.cache_clear()
    yield FamilyFile(path, (tmp_path, builtin_root()))
    compose._compose_cached.cache_clear()


def _no_hydra(*args):
    raise AssertionError("Hydra was run: the stored composition was not read")


def test_a_later_process_reads_the_composition_instead_of_composing(family, monkeypatch):
    first = load_env_spec(family).spec
    assert list((family.path.parent.parent / "cache" / "composed").glob("*.pickle"))
    compose._compose_cached.cache_clear()  # as in a new process
    monkeypatch.setattr(compose, "_hydra_compose", _no_hydra)
    assert load_env_spec(family).spec == first
    with pytest.raises(SpecError, match="Hydra was run"):  # another override list is another composition
        load_env_spec(family, ["task.goal.tolerance=0.03"])


def test_an_edited_file_composes_again_and_the_edit_is_seen(family):
    assert load_env_spec(family).spec.task.goal.tolerance == 0.02
    family.path.write_text(family.path.read_text().replace("tolerance: 0.02", "tolerance: 0.035"))
    compose._compose_cached.cache_clear()
    assert load_env_spec(family).spec.task.goal.tolerance == 0.035


def test_a_new_file_in_a_searched_group_changes_the_key(family):
    before = composed_store.key(family.path, family.search_roots, ())
    robots = family.path.parent.parent / "robots"
    robots.mkdir()
    (robots / "other.yaml").write_text("name: other\n")
    assert composed_store.key(family.path, family.search_roots, ()) != before
    assert composed_store.key(family.path, family.search_roots, ("task.goal.tolerance=0.03",)) != before


def test_a_relative_family_path_is_keyed_by_the_working_folder(family, monkeypatch, tmp_path):
    """A composition records its files by the paths given: one made from a relative path must not serve a
    process in another folder (a Ray worker), where those paths name other files or none."""
    monkeypatch.chdir(tmp_path)
    relative = FamilyFile(family.path.relative_to(tmp_path), family.search_roots)
    here = composed_store.key(relative.path, relative.search_roots, ())
    assert here != composed_store.key(family.path, family.search_roots, ())
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    assert composed_store.key(relative.path, relative.search_roots, ()) != here


def test_a_failed_composition_is_not_stored_and_is_reported_each_time(family):
    family.path.write_text(family.path.read_text().replace("/tasks@task: reach", "/tasks@task: nosuchtask"))
    for _ in range(2):
        compose._compose_cached.cache_clear()
        with pytest.raises(SpecError, match="nosuchtask"):
            load_env_spec(family)
    assert not list((family.path.parent.parent / "cache").rglob("*.pickle"))


def test_the_store_switched_off_stores_nothing(family, monkeypatch):
    monkeypatch.setenv("ENVFACTORY_CACHE_DIR", "off")
    load_env_spec(family)
    assert not list(family.path.parent.parent.rglob("*.pickle"))


def test_the_cache_switched_off_is_no_folder_named_off_for_the_native_kernels(monkeypatch, tmp_path):
    """`off` switches the whole cache off, not just the store: a read-only install keeps its native kernels in the
    system's temporary folder, never in a folder named "off" under the working folder."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("ENVFACTORY_CACHE_DIR", "off")
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setattr(native.os, "access", lambda path, mode: False)  # the package's own folder is read-only
    where = native.folder()
    assert where.is_absolute() and "off" not in where.parts, where
    assert composed_store.folder() is None
