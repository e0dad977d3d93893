from conftest import make_capture

from radarodom.driver.sources import open_source


def test_replay_roundtrip_smoke(tmp_path, small_cfg):
    frames = make_capture(tmp_path / "cap", small_cfg, 5)
    with open_source(f"replay://{tmp_path / 'cap'}?rate=max") as src:
        got = [bytes(f.raw) for f in src]
    assert got == frames
