"""The reference cache lives where each platform keeps per-user caches
(platformdirs), unless VARINT_CACHE_DIR says otherwise."""

from pathlib import Path

import platformdirs
import platformdirs.macos
import platformdirs.unix
import platformdirs.windows
import pytest

from varint.cache import cache_dir


@pytest.fixture
def clean_env(monkeypatch, tmp_path):
    for name in ("VARINT_CACHE_DIR", "XDG_CACHE_HOME"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    return tmp_path / "home"


def test_the_override_wins_everywhere(clean_env, monkeypatch, tmp_path):
    monkeypatch.setenv("VARINT_CACHE_DIR", str(tmp_path / "mine"))
    for cls in (platformdirs.unix.Unix, platformdirs.macos.MacOS):
        monkeypatch.setattr(platformdirs, "PlatformDirs", cls)
        assert cache_dir() == tmp_path / "mine"
    monkeypatch.setenv("VARINT_CACHE_DIR", "~/elsewhere")
    assert cache_dir() == clean_env / "elsewhere"


def test_linux_follows_xdg(clean_env, monkeypatch, tmp_path):
    monkeypatch.setattr(platformdirs, "PlatformDirs", platformdirs.unix.Unix)
    assert cache_dir() == clean_env / ".cache" / "varint"
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_dir() == tmp_path / "xdg" / "varint"


def test_macos_uses_library_caches(clean_env, monkeypatch):
    monkeypatch.setattr(platformdirs, "PlatformDirs", platformdirs.macos.MacOS)
    # The old hand-built rule gave ~/.cache/varint here.
    assert cache_dir() == clean_env / "Library" / "Caches" / "varint"


def test_windows_uses_local_appdata_without_a_vendor_folder(clean_env, monkeypatch):
    local = r"C:\Users\someone\AppData\Local"
    monkeypatch.setattr(platformdirs, "PlatformDirs", platformdirs.windows.Windows)
    monkeypatch.setattr(platformdirs.windows, "get_win_folder",
                        lambda csidl: local if csidl == "CSIDL_LOCAL_APPDATA" else None)
    path = cache_dir()
    # On this (POSIX) test machine the path joins with "/": compare parts.
    assert str(path).startswith(local)
    assert Path(str(path)[len(local):].lstrip("\\/")).parts == ("varint", "Cache")

