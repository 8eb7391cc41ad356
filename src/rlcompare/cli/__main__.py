from rlcompare.cli import main

main()
