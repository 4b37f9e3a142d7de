def test_import():
    import stns_ros
    assert stns_ros.__doc__
