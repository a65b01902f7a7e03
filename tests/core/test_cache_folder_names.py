"""Scene names as cache folder names (`{scene}` in the Cache Folder setting): one plain name per
scene, never a path, never shared by two scene names."""
import re

from lumen_addon.cache import folder_name

NAMES = ["Scene", "Scene.001", "My Scene", "My_Scene", "a/b", "a_b", "a\\b", "..", ".", "", ".hidden",
         "CON", "con.txt", "nul", "Szène", "Szene", "../../etc/passwd", "C:\\x", "trailing.", "x" * 63,
         "x" * 64 + "y", "x" * 64 + "z", "tab\there", "\u0000", "日本語", "Scene\n"]


def test_plain_names_are_kept():
    for name in ("Scene", "Scene.001", "shot_010-v2", "A.B.C"):
        assert folder_name(name) == name


def test_every_name_is_one_safe_folder_and_no_two_names_share_one():
    out = {name: folder_name(name) for name in NAMES}
    for name, folder in out.items():
        assert re.fullmatch(r"[A-Za-z0-9._-]{1,80}", folder), (name, folder)
        assert not folder.startswith(".") and not folder.endswith("."), (name, folder)
        assert folder.split(".")[0].upper() not in ("CON", "NUL", "PRN", "AUX"), (name, folder)
    assert len(set(out.values())) == len(NAMES), out
    assert folder_name("a/b") != folder_name("a_b") and folder_name("My Scene") != folder_name("My_Scene")
