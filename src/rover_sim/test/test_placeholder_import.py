def test_import():
    import rover_sim
    assert rover_sim.__doc__
