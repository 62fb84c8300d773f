from td2adaptor.cli import main

main()
