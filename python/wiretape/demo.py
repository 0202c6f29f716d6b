"""What `make demo` runs. Placeholder."""


def run(repo_root=None):
    print("wiretape demo: not yet")
    return 0
