"""Say which order the tests ran in, also under -q (pytest-randomly prints its seed only in the header)."""


def pytest_terminal_summary(terminalreporter, config):
    seed = getattr(config.option, "randomly_seed", None)
    if config.pluginmanager.hasplugin("randomly") and isinstance(seed, int):
        terminalreporter.write_line(f"test order: shuffled with --randomly-seed={seed} (pass it to repeat this order)")
