"""make test's own setup: the two xdist workers keep each ``xdist_group`` together (``--dist loadgroup``)."""

import pytest

GROUP = "loadgroup_check"


@pytest.mark.xdist_group(GROUP)
def test_loadgroup_marks_a_grouped_test_with_its_group(request):
    """pytest-xdist sends a group's tests to one worker by the group it appends to their node ids; on a pytest where
    that mark no longer takes (9.2.0, pytest-dev/pytest-xdist#1386) the groups are spread over both workers without a
    word: module fixtures built twice, the studies beside each other."""
    if not getattr(request.config.option, "loadgroup", False):  # set in xdist's workers under --dist loadgroup
        pytest.skip("not run under --dist loadgroup")
    assert request.node.nodeid.endswith(f"@{GROUP}"), (
        f"--dist loadgroup did not group {request.node.nodeid} on pytest {pytest.__version__}: install the pytest "
        "that setup.py's test extra pins"
    )
