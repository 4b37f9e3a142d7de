def test_import():
    import stns_core
    assert stns_core.__doc__
