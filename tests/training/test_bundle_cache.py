"""A policy bundle is loaded once per process for the same files, and again when they change."""

import shutil

import drillgym.training  # noqa: F401  (registers residual:)
from drillgym.controllers import make_controller
from drillgym.training import residual_policy
from drillgym.training.policy_bundle import bundle_paths, resolve_policy


def test_controllers_of_one_bundle_share_it_until_its_files_change(tmp_path, monkeypatch):
    monkeypatch.setattr(residual_policy, "_BUNDLES", {})
    src = resolve_policy("shipped")
    dest = tmp_path / src.name
    for a, b in zip(bundle_paths(src), bundle_paths(dest), strict=True):
        if a.exists():
            shutil.copyfile(a, b)
    first, second = make_controller(f"residual:{dest}"), make_controller(f"residual:{dest}")
    assert first is not second and first.policy.bundle is second.policy.bundle
    meta = bundle_paths(dest)[2]
    meta.write_text(meta.read_text() + "\n")  # the same content, another size: a new file
    third = make_controller(f"residual:{dest}")
    assert third.policy.bundle is not first.policy.bundle
    assert len(residual_policy._BUNDLES) == 2
